#include "dtis/interp/taylor.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "dtis/core/error.hpp"

namespace dtis::interp {

FeedProfile ParseFeedProfile(const std::string& name) {
  if (name == "trapezoid") return FeedProfile::kTrapezoid;
  if (name == "exponential") return FeedProfile::kExponential;
  if (name == "bell") return FeedProfile::kBell;
  throw Error("feed profile '{}' is not one of 'trapezoid', 'exponential', 'bell'", name);
}

const char* FeedProfileName(FeedProfile profile) {
  switch (profile) {
    case FeedProfile::kTrapezoid:
      return "trapezoid";
    case FeedProfile::kExponential:
      return "exponential";
    case FeedProfile::kBell:
      return "bell";
  }
  return "?";
}

bool TaylorOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string m) {
    if (why) *why = std::move(m);
    return false;
  };
  if (order != 1 && order != 2)
    return fail(fmt::format("Taylor order must be 1 or 2, got {}", order));
  if (!(period_s > 0.0)) return fail(fmt::format("period must be > 0 s, got {}", period_s));
  if (!(feed_mm_s > 0.0)) return fail(fmt::format("feed must be > 0, got {} mm/s", feed_mm_s));
  if (!(accel_time_s > 0.0)) {
    return fail(fmt::format("acceleration time must be > 0 s, got {}", accel_time_s));
  }
  return true;
}

namespace {
constexpr double kExpRate = 5.0;
// Area under each shape on [0, 1].
double ShapeArea(FeedProfile p) {
  switch (p) {
    case FeedProfile::kTrapezoid:
    case FeedProfile::kBell:
      return 0.5;
    case FeedProfile::kExponential:
      return (1.0 - (1.0 - std::exp(-kExpRate)) / kExpRate) / (1.0 - std::exp(-kExpRate));
  }
  return 0.5;
}
}  // namespace

FeedCommand::FeedCommand(FeedProfile profile, double feed, double accel_time, double length)
    : profile_(profile), feed_(feed), ta_(accel_time) {
  const double area = ShapeArea(profile);
  double cruise_length = length - 2.0 * area * feed * accel_time;
  if (cruise_length < 0.0) {
    // Too short to reach F: keep the time shape, lower the peak feed.
    feed_ = length / (2.0 * area * accel_time);
    cruise_length = 0.0;
  }
  cruise_ = cruise_length / feed_;
  total_ = 2.0 * ta_ + cruise_;
}

double FeedCommand::Shape(double x) const {
  x = std::clamp(x, 0.0, 1.0);
  switch (profile_) {
    case FeedProfile::kTrapezoid:
      return x;
    case FeedProfile::kExponential:
      return (1.0 - std::exp(-kExpRate * x)) / (1.0 - std::exp(-kExpRate));
    case FeedProfile::kBell:
      return 0.5 * (1.0 - std::cos(std::numbers::pi * x));
  }
  return x;
}

double FeedCommand::ShapeSlope(double x) const {
  if (x < 0.0 || x > 1.0) return 0.0;
  switch (profile_) {
    case FeedProfile::kTrapezoid:
      return 1.0;
    case FeedProfile::kExponential:
      return kExpRate * std::exp(-kExpRate * x) / (1.0 - std::exp(-kExpRate));
    case FeedProfile::kBell:
      return 0.5 * std::numbers::pi * std::sin(std::numbers::pi * x);
  }
  return 1.0;
}

double FeedCommand::Feed(double t) const {
  if (t <= 0.0 || t >= total_) return 0.0;
  if (t < ta_) return feed_ * Shape(t / ta_);
  if (t <= ta_ + cruise_) return feed_;
  return feed_ * Shape((total_ - t) / ta_);
}

double FeedCommand::Acceleration(double t) const {
  if (t <= 0.0 || t >= total_) return 0.0;
  if (t < ta_) return feed_ / ta_ * ShapeSlope(t / ta_);
  if (t <= ta_ + cruise_) return 0.0;
  return -feed_ / ta_ * ShapeSlope((total_ - t) / ta_);
}

TaylorResult PlanTaylor(const std::function<void(double, int, Eigen::Vector3d*)>& derivatives,
                        double u0, double u1, double length, const TaylorOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw Error("Taylor interpolator: {}", why);
  const FeedCommand command(options.profile, options.feed_mm_s, options.accel_time_s, length);
  const double T = options.period_s;
  TaylorResult r;
  double u = u0;
  Eigen::Vector3d d[3];
  derivatives(u, 0, d);
  r.u.push_back(u);
  r.points.push_back(d[0]);
  double sum2 = 0.0;
  long counted = 0;
  const long max_steps = static_cast<long>(std::ceil(command.Duration() / T)) + 2;
  for (long k = 0; k < max_steps && u < u1; ++k) {
    const double t = static_cast<double>(k) * T;
    const double V = command.Feed(t), A = command.Acceleration(t);
    derivatives(u, 2, d);
    const double speed = d[1].norm();
    double du = T * V / speed;  // Eq. 8
    if (options.order == 2) {   // Eq. 9
      du += 0.5 * T * T * (A / speed - V * V * d[1].dot(d[2]) / (speed * speed * speed * speed));
    }
    const double next = std::min(u + std::max(du, 0.0), u1);
    const Eigen::Vector3d p = r.points.back();
    derivatives(next, 0, d);
    // The commanded feed over this period is the mean of V over it; compare the chord with it.
    const double commanded = 0.5 * (V + command.Feed(t + T));
    const double produced = (d[0] - p).norm() / T;
    if (commanded > 0.05 * options.feed_mm_s && next < u1) {
      const double f = (produced - commanded) / options.feed_mm_s;
      r.max_fluctuation = std::max(r.max_fluctuation, std::abs(f));
      sum2 += f * f;
      ++counted;
    }
    u = next;
    r.u.push_back(u);
    r.points.push_back(d[0]);
  }
  r.motion_time_s = static_cast<double>(r.u.size() - 1) * T;
  derivatives(u1, 0, d);
  r.end_error_mm = (r.points.back() - d[0]).norm();
  r.rms_fluctuation = counted ? std::sqrt(sum2 / static_cast<double>(counted)) : 0.0;
  for (int k = 0; k < 2; ++k) {
    r.u.push_back(r.u.back());
    r.points.push_back(r.points.back());
  }
  return r;
}

}  // namespace dtis::interp
