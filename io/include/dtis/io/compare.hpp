// The comparison of Beudaert et al. 2014 (Tab. 1), for any surface job: the same passes machined
// from G1 exports and B-spline exports at the job's tolerances, and directly on the surface (DTIS),
// planned by the same interpolator on the same machine, and measured against the exact path.
//
// Exports are made from the exact passes sampled every sample_step_mm: G1 vertices by chordal
// discretization, B-splines by least squares (geometry/path_fit.hpp). G1 variants are planned as
// the G-code program they are written as (corner smoothing with the job's [compare] contour
// tolerance, links as rapids at the link feed); B-spline variants as curves with the exact run's
// links. Deviations are measured at points independent of the samples the exports were made from:
// the export's, between the samples, and the motion's, at every setpoint of a pass.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/job.hpp"

namespace dtis::io {

struct CompareOptions {
  int threads = 0;  // 0: all cores
  // Where the exports are written (G-code, curve files, Siemens program); "" writes none.
  std::string exports_dir;
  // Called when a variant starts: "G1 10 um", ... From the calling thread.
  std::function<void(const std::string&)> progress;
  // Every variant is planned with each of these planners, in this order (empty: the job's).
  std::vector<interp::PlannerKind> planners;
};

struct VariantResult {
  enum class Kind { kG1, kBSpline, kExact } kind = Kind::kExact;
  // "G1 10 um", "B-spline 1 um", "DTIS (exact surface)", "DTIS (axis within 0.1 deg)"
  std::string name;
  interp::PlannerKind planner = interp::PlannerKind::kVpop;
  double tolerance_mm = 0.0;  // 0 for the exact surface
  // The exact surface with the tool axis smoothed within this (deg); 0: the rule's axis.
  double axis_tolerance_deg = 0.0;
  long blocks = 0;             // G1 blocks on the passes, or B-spline control points; 0 for DTIS
  double motion_time_s = 0.0;  // the whole program, links included
  double pass_time_s = 0.0;    // on the passes only
  double export_deviation_mm = 0.0;        // the export's tip path from the exact one, both ways
  double export_axis_deviation_deg = 0.0;  // the export's tool axis from the exact one
  double motion_deviation_mm = 0.0;  // the planned tip positions on the passes from the exact path
  // The planned tool axis from the exact one at the nearest exact point (G1: corner smoothing
  // turns the axis within the job's orientation_tol_mm too).
  double motion_axis_deviation_deg = 0.0;
  interp::VerifyReport verify;
  std::string limiting;    // the axis constraints that decided most periods: "Z jerk 18%, ..."
  double compute_s = 0.0;  // export and planning
  std::vector<std::string> files;  // exports written
  // The planned setpoints (file units: mm, deg) and the constraint that decided each.
  interp::SetpointTable table;
  std::vector<interp::LimiterId> limiters;
  std::vector<std::pair<long, long>> pass_rows;  // the rows of `table` on each pass (PassRows)
};

struct CompareResult {
  std::string job;
  std::string machine;
  int passes = 0;
  double path_length_mm = 0.0;
  double sample_step_mm = 0.0;
  // G1 ..., B-spline ..., DTIS, then DTIS with the axis smoothed (tilt_yaw jobs); each with every
  // planner in turn.
  std::vector<VariantResult> variants;
  std::vector<std::string> notes;  // what was not written, and why
};

// Throws dtis::Error naming the job, pass and what failed.
CompareResult RunCompare(const Job& job, const CompareOptions& options = {});

// A variant as plots and headings name it: "DTIS (exact surface) (vpop)".
std::string VariantLabel(const VariantResult& variant);

// The exact-surface variant with the axis smoothed within `axis_tolerance_deg` (0: the rule's)
// planned with `planner` (the last such variant when none was).
const VariantResult& ExactVariantOf(const CompareResult& result, interp::PlannerKind planner,
                                    double axis_tolerance_deg = 0.0);

// The comparison table: its column names, and one variant's row.
std::vector<std::string> CompareHeader();
std::vector<std::string> CompareCells(const VariantResult& variant);

std::string FormatCompareText(const CompareResult& result);
std::string FormatCompareCsv(const CompareResult& result);
std::string FormatCompareMarkdown(const CompareResult& result);

}  // namespace dtis::io
