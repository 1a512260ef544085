// A G-code program as paths for the interpolator: every run of feed moves at one feed as one
// smoothed chain (geometry/g1_path.hpp), and so every run of consecutive rapids (unless
// blend_rapids is off: then each rapid is a straight move), planned rest to rest one after the
// other by interp::PlanProgram.
//
// Coordinates: X Y Z are the tool tip in the workpiece frame and the rotary words A B C are the
// machine's rotary axes, which set the tool axis through the machine's forward kinematics (TCP
// programming, as LinuxCNC's TCP kinematics or Siemens TRAORI read it). The program starts where
// the machine is (GcodeOptions::from, by default the origin), as LinuxCNC runs it: its first move
// is planned from there. A chain ends, and the machine comes to rest,
// between rapids and feed moves, at a change of feed or of G64 tolerance, after every block under
// G61 or G61.1, at a dwell, a junction with an arc that is not tangent, or a reversal.
#pragma once

#include <array>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/geometry/g1_path.hpp"
#include "dtis/interp/program.hpp"
#include "dtis/io/gcode.hpp"

namespace dtis::io {

struct GcodeOptions {
  // Who reads the program: LinuxCNC's interpreter or dtis' built-in reader (gcode.hpp).
  GcodeInterpreter interpreter = DefaultGcodeInterpreter();
  // LinuxCNC's interpreter only: G43/G43.2 apply this table's tool length offsets (the XYZ
  // translation LinuxCNC adds to the controlled point); none: the programmed tip is planned.
  std::shared_ptr<const ToolTable> tool_table;
  geometry::CornerOptions corners;
  // Feed of rapids (mm/s); 0: as fast as the machine's linear axes allow.
  double rapid_feed_mm_s = 0.0;
  // Largest programmed feed (mm/s): a feed override; infinity: the program's F.
  double max_feed_mm_s = std::numeric_limits<double>::infinity();
  // Consecutive rapids form one chain, their corners smoothed within the contour tolerance (as
  // LinuxCNC blends G0 blocks under G64), instead of a stop at every G0 vertex. The 3-axis
  // plane_cl sample's G1 export at 10 um (`dtis compare --exports`), run as a job: 54.8 s
  // blended, 60.5 s stopping, on the Mikron's real jerk limits.
  bool blend_rapids = true;
  // Arcs join their neighbours without a stop when their tangents differ by at most this (rad).
  double tangent_rad = 1e-3;
  // GcodeSegments (dtis stream): a chain of more blocks than this is smoothed as it is planned
  // and dropped behind the planner (geometry::G1Path::Window), so that memory does not grow with
  // it; 0: every chain whole. BuildGcodePlan (dtis run) holds every chain whole.
  std::size_t window_blocks = 4096;
  // Where the machine is as the program starts, in the program's frame (as LinuxCNC's display
  // shows it): the tip X Y Z (mm), then the machine's rotary axes (degrees), or X Y Z alone (rotary
  // axes at 0); empty: the origin, where LinuxCNC's sim configurations home. The first move is
  // planned from there.
  std::vector<double> from;
  // Instead: the program starts at the end of its first move, which is not planned (`dtis
  // compare`'s exports, whose first move goes to the first pass, where the exact path starts).
  bool start_at_first_move = false;
  // LinuxCNC's numbered parameters the program starts with (GcodeStart::parameters): a parameter
  // file's, then the job's work offsets.
  std::map<int, double> parameters;
  // dtis run holds the whole program, about 1 KB a block: it reads at most this many blocks
  // (GcodeReadOptions::max_blocks, each repetition of a loop counted; the job's [path]
  // max_blocks); 0: no limit.
  long max_blocks = kDefaultMaxBlocks;
  static constexpr long kDefaultMaxBlocks = 200'000;
};

// `options`' start on `machine`: where its tip is and its rotary words, and the parameters.
// Throws dtis::Error "from: ..." when `from` has neither 3 values nor one per axis of the machine.
GcodeStart GcodeStartOf(const GcodeOptions& options, const Machine& machine);
// GcodeOptions::from for the machine at axis positions `q` (planner units): its tip through the
// forward kinematics, and its rotary axes.
std::vector<double> GcodeFrom(const AxisVector& q, const Machine& machine);

// What `dtis run` reads of a job's program: options.max_blocks, the message naming the key of
// `job_file` that raises it.
GcodeReadOptions JobReadOptions(const GcodeOptions& options, const std::string& job_file);

// The machine axis each rotary word (A, B, C) drives, -1 where the machine has none.
std::array<int, 3> RotaryWordAxes(const Machine& machine);

// The feed of a program's rapids (mm/s): options.rapid_feed_mm_s, or when 0 as fast as the
// machine's linear axes allow together. Links to and between G-code jobs move at it too.
double RapidFeed(const GcodeOptions& options, const Machine& machine);

// The tool axis the machine holds at a move's rotary words (degrees), through its forward
// kinematics. Throws dtis::Error if the program moves a rotary axis the machine does not have.
class GcodeToolAxis {
 public:
  GcodeToolAxis(const GcodeProgram& program, const Machine& machine);
  // `uses_rotary`: which of A, B, C the program `file` writes.
  GcodeToolAxis(const std::string& file, const std::array<bool, 3>& uses_rotary,
                const Machine& machine);
  Eigen::Vector3d operator()(const GcodeMove& move) const;

 private:
  const Machine& machine_;
  std::array<int, 3> index_;
};

struct GcodePlan {
  std::vector<std::unique_ptr<PathSource>> paths;
  std::vector<interp::ProgramSegment> segments;  // one per path, in order
  std::vector<bool> rapid;                       // per segment: rapids, not feed moves
  int chains = 0, rapids = 0, corners = 0;  // chains of feed moves; rapid blocks; corners smoothed
  double length_mm = 0.0;                   // tip path length of the feed moves
  double least_time_s = 0.0;                // GcodeSegments::LeastTime() of the whole program
};

// One segment of a program: a chain of feed moves (or of rapids), smoothed, or a lone rapid.
struct GcodeSegment {
  std::unique_ptr<PathSource> path;  // none when only scanned
  interp::VpopOptions options;
  std::string name;  // "<file>: lines 12-40", "<file>:41: rapid", "<file>: lines 12- (...)"
  bool rapid = false;
  int corners = 0;              // smoothed (not counted for a windowed chain)
  bool windowed = false;        // more than window_blocks blocks: read as it is planned
  bool five_axis = false;       // some block turns the tool axis away from where the chain starts
  double dwell_before_s = 0.0;  // G4: held at rest where the segment starts, before it moves
};

// A program's segments one at a time, each built from the moves it takes when it is asked for:
// what BuildGcodePlan returns at once, for a program streamed to a machine, which then holds one
// chain of moves at a time instead of the whole program. Segments and messages are
// BuildGcodePlan's.
// The feed of a program's move (mm/s): a rapid at `rapid_feed_mm_s`, any other move at its F word
// capped by options.max_feed_mm_s.
double MoveFeed(const GcodeMove& m, const GcodeOptions& options, double rapid_feed_mm_s);

// The least time a program takes up to each block: each move at its feed along at least its chord
// (an arc also at least its radius times its sweep), and the dwells. Past `max_s` (a job's 24 h)
// Add throws dtis::Error naming the block, what the program and the block take, and why.
class ProgramLeastTime {
 public:
  ProgramLeastTime(std::string file, double max_s) : file_(std::move(file)), max_s_(max_s) {}
  // Move `m` from `from` at `feed_mm_s`, after the dwell `dwell_s`.
  void Add(const GcodeMove& m, const Eigen::Vector3d& from, double feed_mm_s, double dwell_s);
  double Seconds() const { return seconds_; }

 private:
  std::string file_;
  double max_s_;
  double seconds_ = 0.0;
};

class GcodeSegments {
 public:
  // Yields the program's moves in order, nothing at the end.
  using MoveSource = std::function<std::optional<GcodeMove>()>;
  // `uses_rotary`: the A, B, C words of the whole program (checked against the machine here).
  GcodeSegments(MoveSource next, std::string file, const std::array<bool, 3>& uses_rotary,
                const Machine& machine, const interp::VpopOptions& base,
                const GcodeOptions& options);
  // Nothing after the last segment. Throws dtis::Error "<file>:<line>: ..." as BuildGcodePlan.
  // A windowed chain reads its moves from here as it is built: the next call first reads what
  // it left of its chain (nothing, once it was planned or checked to its end).
  std::optional<GcodeSegment> Next();
  int Rapids() const { return rapids_; }  // rapid blocks read so far
  // The least time the moves read so far can take (s): each move's chord at its feed, rapids at
  // the rapid feed, and the dwells. Next() throws dtis::Error "<file>:<line>: ..." naming the
  // block at which it passes the options' max_motion_s (24 h): a feed, a rapid feed or a dwell
  // mistyped, or a loop that repeats too often.
  double LeastTime() const { return least_.Seconds(); }

  // Windowed chains are smoothed as 3- or 5-axis chains before their moves are read: the
  // five_axis flags of a scan of the same program, windowed chains in order.
  void SetWindowedFiveAxis(std::vector<bool> flags) { windowed_five_axis_ = std::move(flags); }
  // Segments without paths (only name, feed, rapid, windowed and five_axis): for that scan.
  void ScanOnly() { scan_only_ = true; }

 private:
  // A move as read: the chain move it makes, its feed, whether it is a rapid.
  struct Read {
    geometry::ChainMove move;
    double feed = 0.0;
    bool rapid = false;
    double tolerance_mm = 0.0;  // the corners' contour tolerance (G64 P), 0: the job's
    bool stop = false;          // the machine comes to rest at the move's end (G61, G61.1)
    bool rest_before = false;   // and at its start (a dwell before it)
    double dwell_s = 0.0;       // held at rest before it, s
    std::shared_ptr<const geometry::BSplineCurve> nurbs;  // G5.2: the curve, its own chain
  };
  std::optional<Read> ReadMove();
  bool Joins(const Read& r) const;
  void Open(const Read& r);
  void Append(const Read& r);
  GcodeSegment ChainSegment() const;  // the chain's, without its path
  template <typename Moves>
  std::unique_ptr<geometry::G1Path> Smooth(Moves&& moves) const;
  GcodeSegment Flush();
  GcodeSegment FlushWindowed();
  // The next move of the windowed chain being planned; nothing at its end.
  std::optional<geometry::ChainMove> PullJoined();

  MoveSource next_;
  std::string file_;
  const Machine& machine_;
  GcodeToolAxis axis_of_;
  interp::VpopOptions base_;
  GcodeOptions options_;
  double rapid_feed_ = 0.0;
  bool started_ = false, ended_ = false;
  Eigen::Vector3d tip_ = Eigen::Vector3d::Zero(), axis_ = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d start_tip_ = Eigen::Vector3d::Zero();
  // The chain being gathered: its moves (only a window's worth in scan mode or once it is
  // windowed), where it starts, its feed, its last move and where that started.
  std::vector<geometry::ChainMove> chain_;
  std::size_t chain_moves_ = 0;
  Eigen::Vector3d chain_tip_ = Eigen::Vector3d::Zero(), chain_axis_ = Eigen::Vector3d::UnitZ();
  double chain_feed_ = 0.0, chain_tolerance_ = 0.0, chain_dwell_ = 0.0;
  // A dwell before a move that goes nowhere (skipped) is held before the next one.
  bool skipped_rest_ = false;
  double skipped_dwell_ = 0.0;
  int chain_first_line_ = 0;
  bool chain_rapid_ = false, chain_five_axis_ = false;
  geometry::ChainMove last_;
  bool last_stop_ = false;
  std::shared_ptr<const geometry::BSplineCurve> chain_nurbs_;  // the chain is this G5.2 curve
  Eigen::Vector3d last_from_ = Eigen::Vector3d::Zero();
  std::optional<Read> carry_;   // read, the first move of the next chain
  bool windowed_open_ = false;  // a windowed chain is still reading its moves from here
  std::vector<bool> windowed_five_axis_;
  std::size_t windowed_ = 0;  // windowed chains so far
  bool scan_only_ = false;
  int rapids_ = 0, segments_ = 0;
  ProgramLeastTime least_;
};

// `base` carries the period and the tangential limits; each segment gets its own feed. Throws
// dtis::Error "<file>:<line>: ..." for a program the machine cannot run.
GcodePlan BuildGcodePlan(const GcodeProgram& program, const Machine& machine,
                         const interp::VpopOptions& base, const GcodeOptions& options);

}  // namespace dtis::io
