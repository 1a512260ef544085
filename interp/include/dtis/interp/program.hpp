// A program: several paths planned one after the other, each from rest to rest (a surface job's
// passes and the moves that link them, later a G-code program's blocks). Segments are planned in
// parallel (oneTBB) and stitched in order: each starts where the previous one ended, on the same
// solution branch, with rotary axes unwrapped continuously. The result does not depend on the
// number of threads.
#pragma once

#include <exception>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/interp/vpop.hpp"

namespace dtis::interp {

struct ProgramSegment {
  const PathSource* path = nullptr;  // used by one thread at a time
  VpopOptions options;               // per segment (feed differs for links)
  std::string name;                  // "pass 3", "link 2-3 retract", for messages
  // Held at rest where the segment starts before it moves (a G-code dwell), s: rows repeating
  // that position, rounded to whole periods.
  double dwell_before_s = 0.0;
};

// The rows a dwell of `seconds` holds at rest, at `period_s`.
long DwellRows(double seconds, double period_s);

struct ProgramResult {
  std::vector<Setpoint> setpoints;  // indices renumbered 0, 1, ... over the whole program
  std::vector<VpopSummary> segments;
  std::vector<long> first_row;  // row of each segment's first setpoint in `setpoints`
  VpopSummary total;            // counts summed; motion time of the whole program
};

struct ProgramOptions {
  int threads = 0;  // 0: oneTBB's default (all cores)
  // Called after each segment is planned, from any thread: (segments done, segments).
  std::function<void(int, int)> progress;
  // Called while a segment is planned (VpopOptions::progress) and when it is done, from the thread
  // planning it: (the segment's index, the arc length reached in mm, the motion time reached in s).
  std::function<void(int, double, double)> advance;
};

// Throws dtis::Error naming the segment when one cannot be planned or does not start where the
// previous one ended (which would be a position jump).
ProgramResult PlanProgram(const std::vector<ProgramSegment>& segments, const Machine& machine,
                          const ProgramOptions& options = {});

// The two halves of PlanProgram, for programs whose later segments depend on where earlier ones
// really ended (a surface job's links start at the last setpoint of a pass).
struct PlannedSegment {
  std::vector<Setpoint> rows;
  VpopSummary summary;
  std::exception_ptr error;  // a dtis::Error naming the segment, rethrown by Stitch
};
std::vector<PlannedSegment> PlanSegments(const std::vector<ProgramSegment>& segments,
                                         const Machine& machine, const ProgramOptions& options);
ProgramResult Stitch(const std::vector<ProgramSegment>& segments,
                     std::vector<PlannedSegment> planned, const Machine& machine);

// How a segment that starts at `first` joins one that ended at `previous`: the whole turns to add
// to its continuous rotary axes (zero when it starts there), or nothing when it starts elsewhere
// (another branch, or a jump).
std::optional<AxisVector> TurnShift(const Machine& machine, const AxisVector& previous,
                                    const AxisVector& first);

// Whether a segment whose first row is at `first` (turns shifted) continues from `previous` as
// planned: equal but for a few ulps, which the planner's rounding guard absorbs. A hair more (a
// path that stopped within its end tolerance) would go into the first step's jerk over dt^3:
// such a segment is planned again from `previous`.
bool StartsWhereHeld(const AxisVector& previous, const AxisVector& first);

}  // namespace dtis::interp
