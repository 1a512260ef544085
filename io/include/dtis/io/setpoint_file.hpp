// Setpoint CSV files: header `t,X,Y,Z` then the rotary axes (`A,C`), time in s, linear axes in mm,
// rotary axes in degrees, one row per period, every number written so that it reads back to the
// same double.
#pragma once

#include <string>

#include "dtis/core/machine.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/atomic_file.hpp"

namespace dtis::io {

// Reads any setpoint CSV. Throws dtis::Error naming the file, line and column.
interp::SetpointTable ReadSetpoints(const std::string& path);
interp::SetpointTable ParseSetpoints(std::string_view text, const std::string& source_name);

// Writes a table atomically.
void WriteSetpoints(const std::string& path, const interp::SetpointTable& table);

// A sink that converts planner setpoints (mm, rad) to file units and keeps them in a table, which
// the caller then verifies and writes.
class TableSink final : public interp::SetpointSink {
 public:
  TableSink(const Machine& machine, double period_s);
  void Accept(const interp::Setpoint& setpoint) override;
  const interp::SetpointTable& Table() const { return table_; }
  // Per setpoint: arc length and the limiter, for the limiter report.
  const std::vector<double>& ArcLength() const { return s_; }
  const std::vector<interp::LimiterId>& Limiters() const { return limiters_; }

 private:
  interp::SetpointTable table_;
  std::vector<bool> rotary_;
  std::vector<double> s_;
  std::vector<interp::LimiterId> limiters_;
  double period_;
};

}  // namespace dtis::io
