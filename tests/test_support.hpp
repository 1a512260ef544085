// Shared helpers for the tests: the random-suite knobs, sample paths, and an in-memory sink.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <string>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::test {

extern long g_count;          // cases per randomized property test
extern unsigned long g_seed;  // base seed

inline std::string Source(const std::string& relative) {
  return std::string(DTIS_SOURCE_DIR) + "/" + relative;
}

// `f` throws dtis::Error with `fragment` in its message.
template <typename F>
void ExpectError(F&& f, const std::string& fragment) {
  try {
    f();
    FAIL() << "expected an error containing '" << fragment << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

struct Collect final : interp::SetpointSink {
  std::vector<interp::Setpoint> points;
  void Accept(const interp::Setpoint& s) override { points.push_back(s); }
};

// An XYZ machine with the same limits on every axis (mm, s).
inline std::unique_ptr<Machine> Cartesian(double v, double a, double j) {
  std::vector<Axis> axes;
  for (const char* n : {"X", "Y", "Z"}) {
    Axis x;
    x.name = n;
    x.travel_min = -1000;
    x.travel_max = 1000;
    x.vmax = v;
    x.amax = a;
    x.jmax = j;
    axes.push_back(x);
  }
  return std::make_unique<kinematics::XyzMachine>("test", axes);
}

}  // namespace dtis::test
