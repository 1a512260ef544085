// The dtis command: parse arguments, call the libraries, print the summary and errors.
#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>

#include "dtis/core/error.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/io/atomic_file.hpp"
#include "dtis/io/compare.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"

namespace {

// A progress line on a terminal only: pipes and files stay clean.
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled && isatty(fileno(stderr))) {}
  void Update(int done, int total) {
    if (!enabled_) return;
    std::lock_guard lock(mutex_);
    constexpr int kWidth = 30;
    const int filled = total ? kWidth * done / total : kWidth;
    std::fprintf(stderr, "\rplanning [%s%s] %d/%d segments", std::string(filled, '#').c_str(),
                 std::string(kWidth - filled, '.').c_str(), done, total);
    if (done == total) std::fputs("\r\033[K", stderr);
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  std::mutex mutex_;
};

int Run(const std::string& job_path, const std::string& output, const std::string& limiters,
        bool quiet, int threads) {
  const dtis::io::Job job = dtis::io::LoadJob(job_path);
  std::string setpoints = !output.empty()              ? output
                          : !job.setpoints_out.empty() ? job.setpoints_out
                                                       : job.name + ".csv";
  const std::string limiter_file = !limiters.empty() ? limiters : job.limiters_out;
  Progress progress(!quiet);
  dtis::io::RunOptions options;
  options.threads = threads;
  options.progress = [&progress](int done, int total) { progress.Update(done, total); };
  const dtis::io::RunResult result = dtis::io::RunJob(job, options);
  dtis::io::WriteRunOutputs(job, result, setpoints, limiter_file);
  if (!quiet) {
    std::fputs(dtis::io::FormatRunSummary(job, result).c_str(), stderr);
    std::fprintf(stderr, "wrote            %s%s%s\n", setpoints.c_str(),
                 limiter_file.empty() ? "" : ", ", limiter_file.c_str());
  }
  return result.verify.Passed() || job.interpolator != dtis::io::InterpolatorKind::kVpop ? 0 : 3;
}

struct CompareArgs {
  std::string job, csv, markdown, exports;
  bool quiet = false;
  int threads = 0;
};

int Compare(const CompareArgs& a) {
  const dtis::io::Job job = dtis::io::LoadJob(a.job);
  dtis::io::CompareOptions options;
  options.threads = a.threads;
  options.exports_dir = a.exports;
  const bool tty = !a.quiet && isatty(fileno(stderr));
  options.progress = [tty](const std::string& variant) {
    if (tty) std::fprintf(stderr, "\r\033[Kexporting and planning %s ...", variant.c_str());
  };
  const dtis::io::CompareResult result = dtis::io::RunCompare(job, options);
  if (tty) std::fputs("\r\033[K", stderr);
  // Both tables land together or not at all.
  std::optional<dtis::io::AtomicFile> csv, md;
  if (!a.csv.empty()) csv.emplace(a.csv).Write(dtis::io::FormatCompareCsv(result));
  if (!a.markdown.empty()) md.emplace(a.markdown).Write(dtis::io::FormatCompareMarkdown(result));
  if (csv) csv->Commit();
  if (md) md->Commit();
  std::fputs(dtis::io::FormatCompareText(result).c_str(), stdout);
  for (const auto& v : result.variants) {
    if (!v.verify.Passed()) return 3;
  }
  return 0;
}

int Verify(const std::string& setpoints, const std::string& machine_file) {
  const auto machine = dtis::kinematics::LoadMachineFile(machine_file);
  const auto table = dtis::io::ReadSetpoints(setpoints);
  const auto report = dtis::interp::Verify(table, *machine);
  std::fputs(dtis::interp::FormatReport(report).c_str(), stdout);
  return report.Passed() ? 0 : 1;
}

int Faces(const std::string& file) {
  const auto model = dtis::geometry::StepModel::Load(file);
  std::fputs(dtis::geometry::FormatFaceTable(model).c_str(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "dtis: axis setpoints at a fixed period, every axis within its velocity, acceleration and "
      "jerk limits (VPOp, Beudaert et al. 2012)."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "dtis 0.1.0");

  auto* run = app.add_subcommand(
      "run",
      "Plan a job (TOML) and write its setpoints as CSV (t, X, Y, Z then rotary axes in "
      "degrees), atomically. Prints a summary on stderr.");
  std::string job, output, limiters;
  bool quiet = false;
  run->add_option("JOB", job, "job file (see samples/jobs/)")->required();
  run->add_option("-o,--output", output,
                  "setpoint file (default: the job's [output] setpoints, else NAME.csv)");
  run->add_option("--limiters", limiters,
                  "also write, per setpoint, the arc length, feed and which constraint limited it");
  run->add_flag("-q,--quiet", quiet, "print nothing on success");
  int threads = 0;
  run->add_option("-j,--threads", threads,
                  "threads for a surface job's passes (0: all cores); the output is the same")
      ->check(CLI::NonNegativeNumber);

  auto* compare = app.add_subcommand(
      "compare",
      "For a surface job, plan the same passes from G1 and B-spline exports at the job's [compare] "
      "tolerances and directly on the surface, and print one table: blocks, planned time, "
      "deviation from the exact path, verification and the limiting axes.");
  CompareArgs ca;
  compare->add_option("JOB", ca.job, "surface job file (see samples/jobs/)")->required();
  compare->add_option("--csv", ca.csv, "also write the table as CSV");
  compare->add_option("--markdown", ca.markdown, "also write the table as Markdown");
  compare->add_option("--exports", ca.exports,
                      "write the exports there: G1 programs (.ngc), B-spline curve files (.toml), "
                      "Siemens BSPLINE programs (.mpf), LinuxCNC G5.2 programs for XY passes");
  compare->add_flag("-q,--quiet", ca.quiet, "no progress line");
  compare->add_option("-j,--threads", ca.threads, "threads (0: all cores)")
      ->check(CLI::NonNegativeNumber);

  auto* faces = app.add_subcommand(
      "faces",
      "List the faces of a STEP part file: index, surface type, degree, poles, rational, trimmed, "
      "UV bounds and size (mm). Surface jobs select a face by its index.");
  std::string step_file;
  faces->add_option("FILE", step_file, "STEP file (AP203/AP214/AP242)")->required();

  auto* verify = app.add_subcommand(
      "verify",
      "Check any setpoint file against a machine: per axis the largest |v|, |a|, |j| (backward "
      "differences) as a ratio to its limit, the motion time, and rest at both ends. Exit 0 when "
      "every ratio is <= 1 and the sequence starts and ends at rest, 1 otherwise.");
  std::string setpoints, machine;
  verify->add_option("FILE", setpoints, "setpoint CSV")->required();
  verify->add_option("MACHINE", machine, "machine file (see samples/machines/)")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (*run) return Run(job, output, limiters, quiet, threads);
    if (*faces) return Faces(step_file);
    if (*compare) return Compare(ca);
    if (*verify) return Verify(setpoints, machine);
  } catch (const dtis::Error& e) {
    std::fprintf(stderr, "dtis: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dtis: internal error: %s (please report it with the job)\n", e.what());
    return 4;
  }
  return 0;
}
