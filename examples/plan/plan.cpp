// dtis as a library: plan a job file in-process, then plan a path of your own through the
// PathSource contract, and check both with the independent verifier.
//   plan JOB MACHINE
#include <cmath>
#include <cstdio>
#include <dtis/dtis.hpp>
#include <numbers>
#include <optional>
#include <string>

namespace {

// A helix of radius 10 mm and pitch 2 mm about Z, parametrized by its own arc length: the state
// needs nothing but s, and every pose is exact.
class Helix final : public dtis::PathSource {
 public:
  explicit Helix(double turns)
      : turn_(std::hypot(2.0 * std::numbers::pi * kRadius, kPitch)), length_(turns * turn_) {}

  dtis::PathState Start() const override { return {}; }
  std::optional<double> Length() const override { return length_; }

  dtis::PathSample At(const dtis::PathState& /*from*/, double s) const override {
    dtis::PathSample out;
    if (s >= length_) {
      s = length_;
      out.status = dtis::PathStatus::kEnd;
    }
    const double angle = 2.0 * std::numbers::pi * s / turn_;
    out.state.s = s;
    out.pose.tip = {kRadius * std::cos(angle), kRadius * std::sin(angle), kPitch * s / turn_};
    return out;  // the tool axis stays +Z
  }

  // Where a state is, for error messages ("... at helix s = 12.3 mm").
  std::string Describe(const dtis::PathState& state) const override {
    return "helix s = " + std::to_string(state.s) + " mm";
  }

 private:
  static constexpr double kRadius = 10.0, kPitch = 2.0;
  double turn_;  // mm of path per turn
  double length_;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: plan JOB MACHINE\n");
    return 2;
  }
  try {
    // 1. A job file, planned and verified as `dtis run` does, nothing written.
    const dtis::io::Job job = dtis::io::LoadJob(argv[1]);
    const dtis::io::RunResult run = dtis::io::RunJob(job);
    std::printf("dtis %s: %s planned in %zu setpoints, %.3f s of motion, worst ratio %.6f\n",
                dtis::kVersion.data(), job.name.c_str(), run.table.Rows(), run.vpop.motion_time_s,
                run.verify.worst_ratio);

    // 2. A path of your own on a machine from its file.
    const auto machine = dtis::kinematics::LoadMachineFile(argv[2]);
    dtis::interp::VpopOptions options;
    options.period_s = 1e-3;
    options.feed_mm_s = 50.0;
    const Helix helix(2.0);
    dtis::io::TableSink sink(*machine, options.period_s);  // setpoints in file units (mm, deg)
    const dtis::interp::VpopSummary plan = dtis::interp::PlanVpop(helix, *machine, options, sink);
    const dtis::interp::VerifyReport check = dtis::interp::Verify(sink.Table(), *machine);
    std::printf("helix: %zu setpoints, %.3f s of motion, worst ratio %.6f, %s\n",
                sink.Table().Rows(), plan.motion_time_s, check.worst_ratio,
                check.Passed() ? "verified" : "FAILED");
    return run.verify.Passed() && check.Passed() ? 0 : 3;
  } catch (const dtis::Error& e) {
    std::fprintf(stderr, "plan: %s\n", e.what());
    return 1;
  }
}
