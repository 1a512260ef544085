// G1 tool paths smoothed at every corner (Beudaert, Lavernhe, Tournier 2012, "Kinematical analysis
// of 5-axis corner smoothing"), as one PathSource.
//
// A chain of tool poses (tip + unit axis) joined by straight blocks. Each corner is replaced by a
// cubic B-spline with five control points on the two blocks (knots 0 0 0 0 1/2 1 1 1 1): P2 at the
// corner, P1 and P3 at L1 from it, P0 and P4 at L2. Its deviation from the corner is exactly
// eps = L1 cos(alpha / 2) / 2 (Eq. 3), at its middle; it meets the blocks with zero curvature, so
// the path is C2. L2 (never beyond half of either block) is chosen to maximise the corner's
// reachable feed by Eq. 8 on the machine's linear axes. Collinear blocks pass straight through.
//
// 5-axis: the top point (tip + h axis) follows its own polyline; each corner of it is smoothed
// within eps_top with control points scaled by the rate at which the top point moves per mm of
// tip on either block, so that on the straight parts the pose is exactly the programmed linear
// interpolation of tip and top. Inside a corner the top curve's parameter is a quintic in the tip's
// arc length that matches the top point's velocity and acceleration on both blocks: the tool
// orientation is C2 at both connections, which none of the paper's three parametrizations gives.
// Those three are kept as options for comparison.
//
// G2/G3 arcs and helices, in any of the three planes, join the chain where they meet their
// neighbours tangentially; the interpolator's exact axis checks handle the curvature jump there.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::geometry {

// How the top curve of a 5-axis corner is walked as the tip advances.
enum class TopParametrization {
  kC2,               // quintic in the tip's arc length, matched to both blocks (dtis)
  kBottomParameter,  // paper's parametrization 1: u_top = u_bottom
  kUniform,          // paper's parametrization 2: u_top linear in the tip's arc length
  kTopArcLength,     // paper's parametrization 3: top arc length linear in the tip's arc length
};

struct CornerOptions {
  double contour_tol_mm = 0.02;      // eps: deviation of the tip from the programmed corner
  double orientation_tol_mm = 0.05;  // eps_top: deviation of the top point from its corner
  double top_height_mm = 100.0;      // h: where the top point sits on the tool axis
  // Corners whose blocks turn by less than this pass straight through (rad).
  double straight_rad = 1e-9;
  TopParametrization top = TopParametrization::kC2;
  // Programmed feed: Eq. 8 never asks for more (mm/s).
  double feed_mm_s = 1e300;
};

// One element of a chain, as programmed.
struct ChainMove {
  enum class Kind { kLine, kArc } kind = Kind::kLine;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();    // end point, mm
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // tool axis at the end point (unit)
  // Arcs and helices: a point on the axis, the axis (unit: +Z for G17, +Y for G18, +X for G19),
  // the direction about it (G2: clockwise seen from +axis) and the number of turns begun (1: less
  // than one whole turn; LinuxCNC's P word). The tip rises along the axis over the sweep.
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  bool clockwise = false;
  int turns = 1;
  int line = 0;  // source line, for messages
};

// Eq. 8 of the paper on a stretch of path: the largest feed at which no axis exceeds its
// velocity, acceleration or jerk limit, with q_s, q_ss, q_sss from finite differences of exact
// axis positions (spacing h, mm). The least value over [s0, s1] is returned.
double ReachableFeed(const PathSource& path, const Machine& machine, double s0, double s1,
                     double h);

// The unit tangent of a move from `from` at its start and at its end.
Eigen::Vector3d StartTangent(const Eigen::Vector3d& from, const ChainMove& move);
Eigen::Vector3d EndTangent(const Eigen::Vector3d& from, const ChainMove& move);

class G1Path final : public PathSource {
 public:
  // `start`: the pose before the first move. Throws dtis::Error naming the source line when a
  // block has no length, the tip stands still while the axis turns, or a corner cannot be smoothed.
  G1Path(const Eigen::Vector3d& start_tip, const Eigen::Vector3d& start_axis,
         const std::vector<ChainMove>& moves, const Machine& machine,
         const CornerOptions& options = {});

  // A chain too long to hold whole (a CAM finishing program is often one chain of a million
  // blocks: G1 stepovers join its passes), built as the interpolator reaches it and dropped behind
  // what it has released, but for `keep_behind_mm`, which the backward look-ahead from the slow
  // points ahead may still walk. Its poses, slow points, length and errors are the whole chain's,
  // bit for bit; an error is thrown when the chain is built that far (Check builds it to the end).
  struct Window {
    std::vector<ChainMove> first;                    // the chain's first moves
    std::function<std::optional<ChainMove>()> more;  // the rest, nothing at the chain's end
    bool five_axis = false;  // whether any move turns the tool axis away from the start axis
    // mm; 0: 8 times the distance to reach the feed from rest on the slowest linear axis plus a
    // second of feed, at least 200 mm
    double keep_behind_mm = 0.0;
    std::string context;  // put before the messages of errors met while building ("file.ngc")
    // What the user can do when the planner steps back further than the chain keeps (the reader
    // of the chain knows its options: "hold the chain whole with window_blocks = 0").
    std::string behind_remedy;
  };
  G1Path(const Eigen::Vector3d& start_tip, const Eigen::Vector3d& start_axis, Window window,
         const Machine& machine, const CornerOptions& options = {});

  PathState Start() const override { return {}; }
  // A windowed chain knows its length once it is built to its end.
  std::optional<double> Length() const override;
  PathSample At(const PathState& from, double s) const override;
  std::span<const SlowPoint> SlowPoints() const override;
  void Reach(double s) const override;
  void Release(double s) const override;
  std::string Describe(const PathState& state) const override;
  // Where one piece (block, arc, smoothed corner) meets the next.
  std::vector<double> Breaks(double s0, double s1) const override;

  // Builds the chain to its end, dropping what lies behind as it goes (a windowed chain): every
  // error it holds is thrown here. The path is then only good for its length and counts.
  void Check() const;

  Pose PoseAt(double s, int* hint) const;

  // The corners as built, for tests and reports: all of them for a chain built whole, the ones
  // still held for a windowed one.
  struct Corner {
    double s0 = 0.0, s1 = 0.0;  // arc length of the tip where the corner starts and ends
    double l1 = 0.0, l2 = 0.0;  // bottom control lengths (mm)
    double reachable_feed_mm_s = 0.0;
    int line = 0;  // line of the block that ends at the corner
    std::shared_ptr<const BSplineCurve> bottom, top;
  };
  std::span<const Corner> Corners() const { return corners_; }
  std::size_t CornersBuilt() const { return corner_base_ + corners_.size(); }
  bool FiveAxis() const { return five_axis_; }
  bool Windowed() const { return windowed_; }

 private:
  struct Piece {
    enum class Kind { kLine, kArc, kCorner } kind = Kind::kLine;
    double s0 = 0.0, length = 0.0;
    int line = 0;
    // line: start and unit direction; arc: centre and start radius
    Eigen::Vector3d a = Eigen::Vector3d::Zero(), d = Eigen::Vector3d::Zero();
    // line (5-axis): top point at the start and the end
    Eigen::Vector3d ta = Eigen::Vector3d::Zero(), tb = Eigen::Vector3d::Zero();
    double radius = 0.0, sweep = 0.0, dz = 0.0;    // arc: signed sweep (rad), rise (mm)
    Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  // arc: axis
    long corner = -1;
    double w[6] = {};  // corner (kC2): top parameter = sum w_k t^k, t = tip arc length / length
  };
  // A corner's arc-length maps: the tip's, and the top point's (parametrization 3 only).
  struct CornerMaps {
    long corner = -1;
    std::shared_ptr<const ArcLengthMap> bottom, top;
  };
  // How the corner at a vertex is smoothed.
  struct CornerPlan {
    bool corner = false;
    double l1 = 0.0, l2 = 0.0, feed = INFINITY, length = 0.0;
    std::shared_ptr<const BSplineCurve> bottom, top;
    double r_in = 0.0, r_out = 0.0;  // mm of top per mm of tip on either block (5-axis)
  };
  // A programmed vertex: the tip, the top point (tip + h axis), the move that ends there.
  struct Vertex {
    Eigen::Vector3d p, t, axis;
    ChainMove move;  // vertex 0: unused
  };
  // A slow point on its way to the list the interpolator reads: close ones are thinned first.
  struct Candidate {
    double s = 0.0, feed = 0.0;
    long order = 0;  // corner number: ties in feed go to the earlier corner
    enum class State : std::uint8_t { kOpen, kKept, kDropped } state = State::kOpen;
  };

  void Init(const Eigen::Vector3d& start_tip, const Eigen::Vector3d& start_axis,
            const Machine& machine, const CornerOptions& options);
  // Reads one more move (windowed); false at the chain's end.
  bool Pull() const;
  void AddVertex(const ChainMove& move) const;
  const Vertex& V(std::size_t k) const { return vertices_[k - vertex_base_]; }
  CornerPlan PlanCorner(std::size_t k) const;
  // Appends the pieces of the next move and the corner at its end; false when all are built.
  bool Advance() const;
  bool AdvanceRead() const;  // Advance once the moves it needs are read
  // Runs `f`, putting the context before the message of an error it throws.
  template <typename F>
  auto InContext(F&& f) const -> decltype(f());
  void AddLine(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& ta,
               const Eigen::Vector3d& tb, int line) const;
  // Slow feeds of the corners built far enough for them, then the thinning of close ones.
  void Settle() const;
  void Thin(double frontier) const;
  // Builds until every slow point before `s` is decided and the pieces cover `s`.
  void BuildTo(double s) const;
  const CornerMaps& Maps(long corner) const;
  long Find(double s, long hint) const;
  [[gnu::noinline]] void BuildPiecesTo(double s) const;
  [[noreturn, gnu::noinline]] void FailBehind(double s) const;
  const Piece& PieceAt(long i) const { return pieces_[static_cast<std::size_t>(i - piece_base_)]; }
  const Corner& CornerAt(long c) const {
    return corners_[static_cast<std::size_t>(c - static_cast<long>(corner_base_))];
  }

  const Machine* machine_ = nullptr;
  CornerOptions options_;
  double window_ = 0.0;  // slow points closer than this are thinned (mm)
  bool windowed_ = false;
  bool five_axis_ = false;
  double h_ = 100.0;
  TopParametrization top_param_ = TopParametrization::kC2;
  Eigen::Vector3d axis_ = Eigen::Vector3d::UnitZ();  // 3-axis: the constant tool axis
  double keep_behind_ = 0.0;
  std::string behind_remedy_;
  std::string context_;

  // Like every PathSource of a program, a G1Path is evaluated by one thread at a time
  // (interp/program.hpp): what it builds as it goes and its map cache take no lock.
  mutable std::vector<ChainMove> first_;  // windowed: moves given, not read yet
  mutable std::size_t first_next_ = 0;
  mutable std::function<std::optional<ChainMove>()> more_;
  mutable bool read_all_ = false;   // every move is in vertices_ (or was)
  mutable bool built_all_ = false;  // every piece is built
  mutable std::size_t moves_read_ = 0;
  mutable int first_line_ = 0;           // line of the first move, for messages
  mutable std::deque<Vertex> vertices_;  // from vertex_base_: the ones the next pieces need
  mutable std::size_t vertex_base_ = 0;
  mutable std::deque<CornerPlan> plans_;  // per vertex, from plan_base_
  mutable std::size_t plan_base_ = 0;
  mutable std::size_t next_move_ = 0;  // the move whose pieces are built next
  mutable std::vector<Piece> pieces_;  // from piece_base_
  mutable long piece_base_ = 0;
  mutable std::vector<Corner> corners_;  // from corner_base_
  mutable std::size_t corner_base_ = 0;
  mutable std::size_t settled_ = 0;  // corners whose slow feed is known
  mutable std::deque<Candidate> candidates_;
  mutable std::size_t emitted_ = 0;  // candidates_ handed to slow_
  mutable std::vector<SlowPoint> slow_;
  mutable std::size_t slow_dead_ = 0;  // slow_ entries released
  mutable double decided_to_ = 0.0;    // every slow point before this is in slow_
  mutable double released_ = -INFINITY;
  mutable double length_ = 0.0;
  static constexpr std::size_t kCachedCorners = 256;
  mutable std::vector<CornerMaps> maps_;  // slot: corner index modulo kCachedCorners
};

// The moves that link two poses through LinkWaypoints (curve_path.hpp), as few paths as it takes:
// one chain of straight moves whose corners are smoothed within `corners` (so the machine does not
// stop at the waypoints), split only where the link turns back on itself. `corners.feed_mm_s` is
// the link feed. None when the two poses are within 1e-9 mm.
std::vector<std::unique_ptr<PathSource>> LinkMoves(const Pose& from, const Pose& to, double safe_z,
                                                   double clearance, const Machine& machine,
                                                   const CornerOptions& corners,
                                                   bool straight = false);

}  // namespace dtis::geometry
