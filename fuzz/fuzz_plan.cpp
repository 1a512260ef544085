// libFuzzer target for the planner: small random paths planned end to end and checked by the
// independent verifier. The input chooses the path (a B-spline or NURBS curve on the 3-axis
// Mikron, a curve pair on its 5-axis XYZAC, or a G1 program with its corners smoothed), the feed
// and the planner. Any input either is refused with dtis::Error or plans into setpoints that
// verify (every axis within 100 % of its limits, at rest at both ends); anything else aborts,
// and libFuzzer's -timeout (scripts/fuzz sets it) is the wall-clock budget of one plan.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/geometry/bspline_curve.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/interp/program.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/gcode.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"

namespace {

using namespace dtis;

const Machine& Xyz() {
  static const auto m =
      kinematics::LoadMachineFile(DTIS_SOURCE_DIR "/samples/machines/mikron_ucp710_xyz.toml");
  return *m;
}

const Machine& Xyzac() {
  static const auto m =
      kinematics::LoadMachineFile(DTIS_SOURCE_DIR "/samples/machines/mikron_ucp710_xyzac.toml");
  return *m;
}

// A clamped curve of the given degree and pole count, poles in a box of `half` mm about `centre`.
geometry::BSplineCurveData RandomCurve(FuzzedDataProvider& in, int degree, int poles,
                                       const Eigen::Vector3d& centre, double half) {
  geometry::BSplineCurveData d;
  d.degree = degree;
  d.knots.assign(static_cast<std::size_t>(degree + 1), 0.0);
  std::vector<double> inner;
  for (int i = 0; i < poles - degree - 1; ++i) {
    inner.push_back(in.ConsumeFloatingPointInRange(0.0, 1.0));
  }
  std::sort(inner.begin(), inner.end());
  d.knots.insert(d.knots.end(), inner.begin(), inner.end());
  d.knots.insert(d.knots.end(), static_cast<std::size_t>(degree + 1), 1.0);
  for (int i = 0; i < poles; ++i) {
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) p[k] = centre[k] + in.ConsumeFloatingPointInRange(-half, half);
    d.poles.push_back(p);
  }
  if (in.ConsumeBool()) {
    for (int i = 0; i < poles; ++i) d.weights.push_back(in.ConsumeFloatingPointInRange(0.2, 5.0));
  }
  return d;
}

// With DTIS_FUZZ_PRINT set in the environment (running one input by hand), the case is printed
// as a dtis curve file or G-code program, ready to become a job.
bool Printing() {
  static const bool print = std::getenv("DTIS_FUZZ_PRINT") != nullptr;
  return print;
}

void PrintCurve(const geometry::BSplineCurveData& d, const char* name) {
  if (!Printing()) return;
  std::string text = fmt::format("# {}\ndegree = {}\nknots = [{}]\npoles = [", name, d.degree,
                                 fmt::join(d.knots, ", "));
  for (std::size_t i = 0; i < d.poles.size(); ++i) {
    text += fmt::format("{}[{}, {}, {}]", i ? ", " : "", d.poles[i].x(), d.poles[i].y(),
                        d.poles[i].z());
  }
  text += "]\n";
  if (!d.weights.empty()) text += fmt::format("weights = [{}]\n", fmt::join(d.weights, ", "));
  std::fputs(text.c_str(), stderr);
}

void Check(const interp::SetpointTable& table, const Machine& machine, const char* what) {
  if (table.Rows() < 2) return;
  const interp::VerifyReport r = interp::Verify(table, machine);
  if (!r.Passed()) {
    std::fprintf(stderr, "%s: not verified: worst ratio %.9f (%s), at rest %d/%d, period %d\n",
                 what, r.worst_ratio, r.worst.c_str(), r.starts_at_rest, r.ends_at_rest,
                 r.uniform_period);
    std::abort();
  }
}

void PlanCurve(FuzzedDataProvider& in, const interp::VpopOptions& options, bool five_axis) {
  const int degree = in.ConsumeIntegralInRange(1, 4);
  const int poles = in.ConsumeIntegralInRange(degree + 1, 8);
  const Machine& machine = five_axis ? Xyzac() : Xyz();
  const Eigen::Vector3d centre(0, 0, five_axis ? -150 : 0);
  auto bottom = RandomCurve(in, degree, poles, centre, 60.0);
  std::unique_ptr<geometry::CurvePath> path;
  if (five_axis) {
    // The top curve: the bottom raised by a tool axis that leans at most about 30 degrees.
    geometry::BSplineCurveData top = bottom;
    for (auto& p : top.poles) {
      p += Eigen::Vector3d(in.ConsumeFloatingPointInRange(-15.0, 15.0),
                           in.ConsumeFloatingPointInRange(-15.0, 15.0), 30.0);
    }
    PrintCurve(bottom, "bottom");
    PrintCurve(top, "top");
    path = std::make_unique<geometry::CurvePath>(geometry::BSplineCurve(std::move(bottom)),
                                                 geometry::BSplineCurve(std::move(top)));
  } else {
    PrintCurve(bottom, "curve");
    path = std::make_unique<geometry::CurvePath>(geometry::BSplineCurve(std::move(bottom)),
                                                 Eigen::Vector3d::UnitZ());
  }
  io::TableSink sink(machine, options.period_s);
  interp::PlanVpop(*path, machine, options, sink);
  Check(sink.Table(), machine, five_axis ? "curve pair (XYZAC)" : "curve (XYZ)");
}

void PlanG1(FuzzedDataProvider& in, const interp::VpopOptions& options) {
  std::string text = "G21 G90 G94\n";
  const int moves = in.ConsumeIntegralInRange(1, 10);
  for (int i = 0; i < moves; ++i) {
    text += fmt::format(
        "G1 X{:.4f} Y{:.4f} Z{:.4f} F{:.1f}\n", in.ConsumeFloatingPointInRange(-50.0, 50.0),
        in.ConsumeFloatingPointInRange(-50.0, 50.0), in.ConsumeFloatingPointInRange(-20.0, 20.0),
        in.ConsumeFloatingPointInRange(60.0, 12000.0));
  }
  if (Printing()) std::fputs(text.c_str(), stderr);
  io::GcodeOptions g;
  g.interpreter = io::GcodeInterpreter::kDtis;
  g.corners.contour_tol_mm = in.ConsumeFloatingPointInRange(0.001, 0.5);
  const io::GcodeProgram program = io::ParseGcode(text, "fuzz.ngc");
  const io::GcodePlan plan = io::BuildGcodePlan(program, Xyz(), options, g);
  interp::ProgramOptions po;
  po.threads = 1;
  const interp::ProgramResult result = interp::PlanProgram(plan.segments, Xyz(), po);
  io::TableSink sink(Xyz(), options.period_s);
  for (const auto& sp : result.setpoints) sink.Accept(sp);
  Check(sink.Table(), Xyz(), "G1 program");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  interp::VpopOptions options;
  options.period_s = 1e-3;
  options.feed_mm_s = in.ConsumeFloatingPointInRange(5.0, 300.0);
  options.planner = in.ConsumeBool() ? interp::PlannerKind::kLookAhead : interp::PlannerKind::kVpop;
  const int kind = in.ConsumeIntegralInRange(0, 2);
  if (Printing()) {
    std::fprintf(stderr, "# feed %.17g mm/s, planner %s\n", options.feed_mm_s,
                 options.planner == interp::PlannerKind::kLookAhead ? "lookahead" : "vpop");
  }
  try {
    if (kind == 2) {
      PlanG1(in, options);
    } else {
      PlanCurve(in, options, kind == 1);
    }
  } catch (const dtis::Error&) {
  }
  return 0;
}
