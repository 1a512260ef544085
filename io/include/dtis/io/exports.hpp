// The programs a CAM system hands a CNC for a surface job's passes (Beudaert et al. 2014, Tab. 1):
// G1 blocks at a chordal tolerance, and fitted cubic B-splines, as text a controller reads.
//
// - G1: RS274/NGC as dtis' own reader and LinuxCNC read it: X Y Z the tool tip (mm), A B C the
//   machine's rotary axes (degrees, from its inverse transform, continuous), one G1 per vertex,
//   passes linked by G0 rapids through the same waypoints as the exact run's links.
// - B-spline: dtis curve files (one per pass; 5-axis: the bottom/top pair); a Siemens 840D-style
//   program (BSPLINE SD=3 with the knot intervals as PL, and in 5-axis TRAORI ORICURVE with the
//   top curve's poles as XH YH ZH); LinuxCNC G5.2/G5.3 for passes in a plane z = const (G5.2 is
//   XY only and takes no knots: it assumes them uniform, so fit with uniform_knots).
//
// Numbers are written with 6 decimals (1 nm, 1e-6 deg); the in-memory G1 program holds exactly the
// values written, so reading the text back gives the same program, bit for bit.
#pragma once

#include <string>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/pose.hpp"
#include "dtis/geometry/bspline_curve.hpp"
#include "dtis/geometry/link_height.hpp"
#include "dtis/io/gcode.hpp"

namespace dtis::io {

// How passes are linked (as geometry::LinkWaypoints does): back off, rise, traverse at the height
// `heights` gives for the two poses (none: at traverse_z_mm), come down.
struct LinkSpec {
  double traverse_z_mm = 0.0;
  double clearance_mm = 0.0;
  const geometry::LinkHeights* heights = nullptr;
  // straight[p]: pass p is reached straight from the end of pass p - 1, not by a link (the tool
  // rides over what lies between, strategies::SurfacePass::RidesOverFromPrevious). Shorter than
  // the passes: the rest are linked.
  std::vector<bool> straight;
  bool Straight(std::size_t p) const { return p < straight.size() && straight[p]; }
};

struct GcodeExport {
  std::string text;
  GcodeProgram program;  // what the text says, as ReadGcode would return it
};

// `passes[k]`: the poses of pass k's blocks, start included. `header`: comment lines. Throws
// dtis::Error naming the pass and pose the machine cannot reach.
GcodeExport ExportG1(const std::vector<std::vector<Pose>>& passes, const Machine& machine,
                     double feed_mm_min, const LinkSpec& links,
                     const std::vector<std::string>& header, const std::string& file_name);

// One fitted pass: the tip curve and, in 5-axis, the top curve (same knots), top_height_mm up
// the tool axis.
struct SplinePass {
  const geometry::BSplineCurve* bottom = nullptr;
  const geometry::BSplineCurve* top = nullptr;      // null: fixed tool axis
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // the fixed axis when top is null
};

// A dtis curve file (io/curve_file.hpp) holding one pass, every number exact.
std::string FormatCurveFile(const SplinePass& pass, const std::vector<std::string>& header);

// Siemens 840D-style BSPLINE program of all passes, linked by G0 through the links' waypoints
// (orientation as A3 B3 C3 in 5-axis). Not run on a controller here: the syntax follows the
// SINUMERIK programming manual (BSPLINE, SD, PL, TRAORI, ORIWKS, ORICURVE, XH YH ZH).
std::string FormatSiemensBspline(const std::vector<SplinePass>& passes, double feed_mm_min,
                                 const LinkSpec& links, const std::vector<std::string>& header);

// LinuxCNC G5.2/G5.3 NURBS blocks of passes that lie in planes z = const with a fixed vertical
// axis, fitted with uniform knots. Throws dtis::Error naming the first pass that is not such.
std::string FormatLinuxcncNurbs(const std::vector<SplinePass>& passes, double feed_mm_min,
                                const LinkSpec& links, const std::vector<std::string>& header);

// True when every pass lies in a plane z = const (within tol_mm) with a fixed vertical axis: the
// passes LinuxCNC's G5.2 can carry.
bool PlanarXY(const std::vector<SplinePass>& passes, double tol_mm);

}  // namespace dtis::io
