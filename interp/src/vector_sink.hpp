// A sink that keeps every setpoint it is handed, in order (the planners' own internal use: a
// program's segments planned apart before they are stitched, the plans the least-time planner
// starts from).
#pragma once

#include <vector>

#include "dtis/interp/vpop.hpp"

namespace dtis::interp {

class VectorSink final : public SetpointSink {
 public:
  void Accept(const Setpoint& setpoint) override { rows.push_back(setpoint); }
  std::vector<Setpoint> rows;
};

}  // namespace dtis::interp
