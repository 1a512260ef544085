// libFuzzer target: any input either parses or throws dtis::Error; nothing else may escape.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "dtis/core/error.hpp"
#include "dtis/io/setpoint_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    dtis::io::ParseSetpoints(text, "fuzz.csv");
  } catch (const dtis::Error&) {
  }
  return 0;
}
