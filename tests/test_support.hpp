// Shared helpers for the tests: the random-suite knobs, sample paths, and an in-memory sink.
#pragma once

#include <random>
#include <string>
#include <vector>

#include "dtis/interp/vpop.hpp"

namespace dtis::test {

extern long g_count;          // cases per randomized property test
extern unsigned long g_seed;  // base seed

inline std::string Source(const std::string& relative) {
  return std::string(DTIS_SOURCE_DIR) + "/" + relative;
}

struct Collect final : interp::SetpointSink {
  std::vector<interp::Setpoint> points;
  void Accept(const interp::Setpoint& s) override { points.push_back(s); }
};

}  // namespace dtis::test
