// Feeding a running machine (docs/design.md: the commit horizon). A job's segments are planned one
// after the other on a worker thread; each setpoint is handed over as soon as back-off can no
// longer reach it, together with the stop to rest from it, and a feeder writes them to the CNC at
// its own pace, a bounded number of periods ahead of it. Whatever stops the stream early (an
// abort, a planner that falls behind, a path that cannot be followed) plays the stop that was
// offered with the last setpoint written, so the machine always ends at rest within every axis
// limit, never with a cut. Memory stays bounded whatever the job's length.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/cancel.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"

namespace dtis::io {

// ---- what is planned: a job's paths, one after the other

struct StreamSegment {
  std::shared_ptr<const PathSource> path;  // keeps what it points into alive
  interp::VpopOptions options;
  std::string name;             // "pass 3", "link from pass 3 to pass 4", "contour 2"
  int pass = -1;                // surface jobs: the pass (0-based); -1 for links and other paths
  double dwell_before_s = 0.0;  // held at rest before it moves (G4), as interp::Stitch holds it
};

class SegmentSource {
 public:
  virtual ~SegmentSource() = default;
  // The next segment, to start where the machine is now (`at`, the last setpoint streamed; none
  // before the first), or nothing at the end of the job.
  virtual std::optional<StreamSegment> Next(const std::optional<AxisVector>& at) = 0;
  // Where the machine will be before the first segment, when that is known only after the source
  // was built (a daemon validates a job when it is submitted and links it when it starts): a link
  // leads from there, as from JobSegments' `from`. Call before the first Next.
  virtual void StartFrom(const std::optional<AxisVector>& from) { (void)from; }
  // What the job leaves out, for the operator before the machine moves (a surface job's
  // stretches where the tool does not fit, strategies::PassList::UnreachableText), or "".
  virtual std::string Notes() const { return ""; }
};

// The segments of any job, in the order `dtis run` plans them (passes and links of a surface job,
// contours and rapids of a G-code program, the one path of a line or curve job). When `from` is
// given and differs from the job's start, a link (retract, traverse at a safe height, plunge)
// leads from there first. `safe_z_mm`: the traverse height of such a link (surface jobs: the
// job's own; others: above both ends by `clearance_mm`). A G-code program is read whole first,
// and refused when its moves take more than a job may (interp::kMaxMotionS), an endless loop
// too. `cancel` (which must outlive the call), once requested, makes it throw soon (a surface
// job: once its passes are traced).
std::unique_ptr<SegmentSource> JobSegments(const Job& job, const Machine& machine,
                                           const std::optional<AxisVector>& from = std::nullopt,
                                           double clearance_mm = 5.0, Cancel* cancel = nullptr);

// ---- where setpoints go

// One row per period, in machine units at the edge (mm, degrees).
struct StreamRow {
  long row = 0;     // period number since the stream started
  long index = 0;   // planner index over the job (equal to row unless held at rest)
  double s = 0.0;   // arc length in the current segment, mm
  const double* q;  // one value per axis, mm and deg
  int segment = 0;  // 0-based
};

class CncOutput {
 public:
  virtual ~CncOutput() = default;
  virtual void Write(const StreamRow& row) = 0;
  virtual void Flush() {}
  // Rows written that the machine has not played yet, when the output can tell (a HAL stream).
  virtual std::optional<long> Queued() const { return std::nullopt; }
  // End of stream (flush, pad).
  virtual void Close() {}
};

// Lines for LinuxCNC's halstreamer: one line per period, one number per axis (mm, deg), and the
// row number + 1 when `index_column` (a u32 pin that tells which setpoint a HAL sample holds).
// Every number reads back as the same double. Close() repeats the last line once: halstreamer drops
// the last line of a stream whose length is a multiple of its depth, and a repeated rest row is
// harmless.
class HalstreamerOutput final : public CncOutput {
 public:
  // Writes to `file` (not owned; stdout or an opened FIFO).
  HalstreamerOutput(std::FILE* file, int axes, bool index_column);
  void Write(const StreamRow& row) override;
  void Flush() override;
  void Close() override;

 private:
  std::FILE* file_;
  int axes_;
  bool index_column_;
  std::string last_;
};

// ---- the stream itself

// The commit horizon a stream uses unless the job sets one, periods.
inline constexpr std::size_t kStreamCommitHorizon = 256;
// The job's commit_horizon if it sets one, else kStreamCommitHorizon.
std::size_t StreamHorizon(const Job& job);

struct StreamOptions {
  double period_s = 1e-3;
  // Setpoints written ahead of the machine (the CNC's FIFO depth we aim for), periods.
  long buffer_periods = 200;
  // Steps the planner keeps open to back-off before handing them over (>= 8), periods.
  std::size_t commit_horizon = kStreamCommitHorizon;
  // Write at the machine's pace (the clock, or the output's own queue when it can tell) instead
  // of as fast as the output takes rows (a file, a pipe into a program that paces itself).
  bool realtime = false;
  // With `realtime`: when nothing new is planned and fewer than this many periods are left in the
  // machine's buffer, play the stop (an underrun), periods.
  long low_water_periods = 20;
  // Keep every row written, and the constraint that decided it, in the result (for a report).
  bool keep_rows = false;
  // Test hook: the planner sleeps this long per setpoint, to make it fall behind.
  long slow_planner_us = 0;
};

enum class StreamEnd { kComplete, kAborted, kStarved, kFailed };
const char* StreamEndName(StreamEnd end);

// Live figures, readable from any thread while the stream runs.
struct StreamStatus {
  std::atomic<long> rows{0};       // written to the machine
  std::atomic<int> segment{0};     // being written (0-based)
  std::atomic<int> pass{-1};       // surface jobs: being written (0-based), -1 on links
  std::atomic<double> s_mm{0.0};   // arc length of the last row written, in its segment
  std::atomic<long> queued{0};     // planned rows waiting to be written
  std::atomic<long> ahead{0};      // rows the machine holds (or is estimated to hold)
  std::atomic<long> underruns{0};  // times the planner fell behind (the stop was played)
  std::atomic<long> holds{0};      // rows held at rest while the planner caught up
  std::atomic<int> segments_planned{0};
};

struct StreamResult {
  StreamEnd end = StreamEnd::kComplete;
  std::string error;                 // for kFailed: the planner's message
  long rows = 0;                     // written
  long stop_rows = 0;                // of those, from the stop played at the end
  int segments = 0;                  // planned (started)
  std::optional<AxisVector> last_q;  // where the machine stopped (mm, rad)
  interp::VerifyReport verify;       // of exactly the rows written
  double compute_s = 0.0;            // planner thread busy time (not waiting for room in the queue)
  double wall_s = 0.0;
  long peak_queued = 0;
  // Most rows handed over at once: an abort plays at most this many planned rows before the stop.
  long largest_handover = 0;
  // With StreamOptions::keep_rows: the rows written (t = row * period, mm, deg) and what decided
  // each.
  interp::SetpointTable table;
  std::vector<interp::LimiterId> limiters;
};

class Stream {
 public:
  Stream(const Machine& machine, const StreamOptions& options);
  ~Stream();

  // Plans `segments` on a worker thread and writes every setpoint to `out` (and to `record`,
  // committed at the end, with t = row * period) on the calling thread until the job ends, Abort()
  // is called or the planner fails or falls behind. Ends at rest in every case but one: `out`
  // fails (its reader gone), when it throws that error after committing `record` with the rows
  // written until then (Recorded() tells), the evidence of what the machine may have received.
  StreamResult Run(SegmentSource& segments, CncOutput& out, SetpointWriter* record = nullptr);
  // Whether Run committed its recording (also when it threw).
  bool Recorded() const { return recorded_; }

  // From any thread: end the stream as soon as the stop allows.
  void Abort();
  // From any thread: hold at rest at the end of the current segment until Resume().
  void Pause();
  void Resume();
  bool Paused() const { return paused_; }
  const StreamStatus& Status() const { return status_; }

 private:
  struct Shared;
  const Machine& machine_;
  StreamOptions o_;
  StreamStatus status_;
  std::atomic<bool> abort_{false};
  std::atomic<bool> paused_{false};
  bool recorded_ = false;
  std::unique_ptr<Shared> shared_;
};

}  // namespace dtis::io
