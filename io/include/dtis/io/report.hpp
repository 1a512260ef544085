// A run as one self-contained HTML file: the tool path coloured by feed, the feed (along a surface
// job's passes, else against time) with the programmed feed and the constraint that decided each
// period, how close every axis comes to each limit (|value| / limit in %, and the share of periods
// at it), every axis' position, velocity, acceleration and jerk on demand, and the verifier's
// summary. Every plot is built for the page and, for `dtis figures`, for print.
// plotly.js is embedded at report time, so the file opens offline. Long runs are decimated for
// display without hiding peaks: each pixel-wide bucket of a time series keeps its min and max.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/geometry/face_mesh.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/compare.hpp"
#include "dtis/io/job.hpp"

namespace dtis::io {

// One row of a report's header: what the run is ("machine", "my_mill (mill.toml)").
using ReportFact = std::pair<std::string, std::string>;

struct ReportInput {
  std::string title;  // the job or file the run came from
  // The header: machine, job, part, face, tool, strategy, ... The report adds the dtis version
  // and the date it was made.
  std::vector<ReportFact> about;
  const Machine* machine = nullptr;              // the axes and limits
  const interp::SetpointTable* table = nullptr;  // file units (mm, deg)
  // The run's own verification of `table`, when it has one; else the report verifies it.
  const interp::VerifyReport* verify = nullptr;
  std::vector<interp::LimiterId> limiters;  // per setpoint when known (VPOp runs)
  double programmed_feed_mm_min = 0.0;      // 0: not known
  double compute_s = -1.0;                  // < 0: not known
  int passes = 0;                           // surface jobs
  // Surface jobs: the rows [first, end) of `table` on each pass (RunResult::pass_rows); the feed
  // is then drawn against the arc length along the passes, links left out. Empty: against time.
  std::vector<std::pair<long, long>> pass_rows;
  // Surface jobs: every stretch the passes left out where the tool does not fit, a line each
  // (RunResult::unreachable_all), listed whole under the summary; "" for none.
  std::string unreachable;
  // Surface jobs: the face, drawn under the path (MeshJobSurface).
  const geometry::FaceMesh* surface = nullptr;
  // `dtis compare`: the comparison table and every variant's feed against time on one plot; the
  // rest of the report shows `table`, one of its variants (the exact surface's).
  const CompareResult* compare = nullptr;
  std::string shown;  // with `compare`: which variant the rest of the report shows
};

// Time-series points shown per plot (min and max of each of half as many buckets).
inline constexpr std::size_t kReportPoints = 4000;
// An axis is at a limit in a period where |value| is at least this share of the limit.
inline constexpr double kAtLimit = 0.99;

// The indices of `values` to draw at most `points` of them: the first and last, and in each of
// points / 2 equal buckets the rows of the smallest and the largest value, in order.
std::vector<std::size_t> DecimateMinMax(const std::vector<double>& values, std::size_t points);

// A job's header rows: the job file, the machine, what is machined (the STEP file and face, the
// G-code program, the curve or the line), tool, orientation and strategy, planner, feed and period.
std::vector<ReportFact> JobFacts(const Job& job, const Machine& machine);

// The report as HTML, with `plotly_js` (the library's source) inlined.
std::string RenderReport(const ReportInput& input, const std::string& plotly_js);

// Where plotly.min.js is read from: $DTIS_PLOTLY_JS, else the copy scripts/bootstrap installs.
std::string PlotlyPath();

// plotly.js from PlotlyPath(). Throws dtis::Error when it is missing (naming the path and how to
// get it): call it before the work the report is about, so a missing library fails at once.
std::string LoadPlotly();

}  // namespace dtis::io
