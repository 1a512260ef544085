// Milling tools and their cutter location. A tool is a torus around its axis: corner radius r and
// the radius R of the circle its corner centres run on, so that the tool radius is R + r. Ball end:
// R = 0. Flat end: r = 0. Bull nose: both.
//
// The cutter location is the tool tip (the centre of the tool's bottom, on its axis). With contact
// point P, unit surface normal n (pointing out of the material) and unit tool axis a (tip towards
// spindle), the corner centre touching P is Q = P + r n. The tool touches with the outer half of
// its corner, whose own outward normal there is -n: Q lies on the corner circle in the direction
// of -n's part across the axis, so the axis passes at distance R from Q along
// w = (n - (n.a) a) / |n - (n.a) a|, and
//     tip = P + r n + R w - r a.
// (On a plane sloping down towards +x, a flat end touches with its uphill edge and its axis lies
// R downhill of the contact point, along w.)
// When n is along a and R > 0 (a bull nose or flat end sitting flat), w is undefined: the contact
// is anywhere on the flat bottom and the cutter location is not a function of the contact point.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <string>

namespace dtis::geometry {

struct Tool {
  enum class Kind { kBallEnd, kBullNose, kFlatEnd };
  Kind kind = Kind::kBallEnd;
  double radius = 0.0;         // tool radius R + r, mm
  double corner_radius = 0.0;  // r, mm (= radius for a ball end, 0 for a flat end)

  double TorusRadius() const { return radius - corner_radius; }  // R
  // Throws dtis::Error if the radii do not describe a tool of this kind.
  void Validate() const;
  std::string Describe() const;
};

// |n - (n.a) a| below this: the contact point does not fix the cutter location (see above).
inline constexpr double kFlatContactSine = 1e-6;

// The tool tip for contact point p, unit normal n and unit axis a. T is double or a ceres::Jet.
// Returns false when the tool sits flat (R > 0 and n along a).
template <typename T>
bool TipFromContact(const Tool& tool, const Eigen::Matrix<T, 3, 1>& p,
                    const Eigen::Matrix<T, 3, 1>& n, const Eigen::Matrix<T, 3, 1>& a,
                    Eigen::Matrix<T, 3, 1>* tip) {
  using std::sqrt;
  const T r(tool.corner_radius);
  const double big_r = tool.TorusRadius();
  *tip = p + n * r - a * r;
  if (big_r == 0.0) return true;
  const Eigen::Matrix<T, 3, 1> side = n - a * n.dot(a);
  const T norm = sqrt(side.squaredNorm());
  if (!(norm > T(kFlatContactSine))) return false;
  *tip += side * (T(big_r) / norm);
  return true;
}

}  // namespace dtis::geometry
