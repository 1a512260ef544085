// dtis_make_part: writes the parts dtis generates for its samples (samples/parts/PROVENANCE.md).
//   dtis_make_part cubic_wave samples/parts/cubic_wave.stp
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <filesystem>

#include "parts.hpp"

int main(int argc, char** argv) {
  CLI::App app{"Writes a part dtis generates for its samples as STEP"};
  std::string name, out;
  app.add_option("part", name, "the part: cubic_wave")
      ->required()
      ->check(CLI::IsMember({"cubic_wave"}));
  app.add_option("output", out, "the STEP file to write")->required();
  CLI11_PARSE(app, argc, argv);
  // Written beside the output and renamed over it, so a failed write leaves no half file.
  const std::string partial = out + ".partial";
  try {
    dtis::parts::WriteStep(dtis::parts::CubicWaveFace(), partial);
    std::filesystem::rename(partial, out);
  } catch (const std::exception& e) {
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    fmt::print(stderr, "dtis_make_part: {}: {} (check that its folder exists and is writable)\n",
               out, e.what());
    return 1;
  }
  return 0;
}
