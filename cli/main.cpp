// The dtis command: parse arguments, call the libraries, print the summary and errors.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>

#include "dtis/core/error.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"

namespace {

int Run(const std::string& job_path, const std::string& output, const std::string& limiters,
        bool quiet) {
  const dtis::io::Job job = dtis::io::LoadJob(job_path);
  std::string setpoints = !output.empty()              ? output
                          : !job.setpoints_out.empty() ? job.setpoints_out
                                                       : job.name + ".csv";
  const std::string limiter_file = !limiters.empty() ? limiters : job.limiters_out;
  const dtis::io::RunResult result = dtis::io::RunJob(job);
  dtis::io::WriteRunOutputs(job, result, setpoints, limiter_file);
  if (!quiet) {
    std::fputs(dtis::io::FormatRunSummary(job, result).c_str(), stderr);
    std::fprintf(stderr, "wrote            %s%s%s\n", setpoints.c_str(),
                 limiter_file.empty() ? "" : ", ", limiter_file.c_str());
  }
  return result.verify.Passed() || job.interpolator != dtis::io::InterpolatorKind::kVpop ? 0 : 3;
}

int Verify(const std::string& setpoints, const std::string& machine_file) {
  const auto machine = dtis::kinematics::LoadMachineFile(machine_file);
  const auto table = dtis::io::ReadSetpoints(setpoints);
  const auto report = dtis::interp::Verify(table, *machine);
  std::fputs(dtis::interp::FormatReport(report).c_str(), stdout);
  return report.Passed() ? 0 : 1;
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
    if (*run) return Run(job, output, limiters, quiet);
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
