// Setpoint CSV files: header `t,X,Y,Z` then the rotary axes (`A,C`), time in s, linear axes in mm,
// rotary axes in degrees, one row per period, every number written so that it reads back to the
// same double.
#pragma once

#include <string>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/atomic_file.hpp"

namespace dtis::io {

// Reads any setpoint CSV. Throws dtis::Error naming the file, line and column.
interp::SetpointTable ReadSetpoints(const std::string& path);
interp::SetpointTable ParseSetpoints(std::string_view text, const std::string& source_name);

// A limiter report (`dtis run --limiters`: header `t,s,feed,limiter,axis`), the constraint that
// decided each setpoint; `axes` are the machine's axis names the axis column may hold. Throws
// dtis::Error naming the file, line and column.
std::vector<interp::LimiterId> ReadLimiters(const std::string& path,
                                            const std::vector<std::string>& axes);
std::vector<interp::LimiterId> ParseLimiters(std::string_view text, const std::string& source_name,
                                             const std::vector<std::string>& axes);
// The limiter report of a planned table: per row its time, arc length (mm), feed (mm/s) and the
// constraint that decided it, with the axis for axis constraints.
std::string FormatLimiters(const interp::SetpointTable& table,
                           const std::vector<double>& arc_length,
                           const std::vector<interp::LimiterId>& limiters, double period_s);

// Writes a table atomically.
void WriteSetpoints(const std::string& path, const interp::SetpointTable& table);

// The same file written row by row, in constant memory (a stream), renamed into place on Commit().
class SetpointWriter {
 public:
  SetpointWriter(const std::string& path, const std::vector<std::string>& axes);
  void Row(double t, const double* values);  // one value per axis, file units
  void Commit();                             // Finish(), then the file's Commit()
  // Hands every row to the file and returns it, to commit with others (CommitTogether).
  AtomicFile& Finish();

 private:
  AtomicFile file_;
  std::string buffer_;
  std::size_t axes_;
};

// Every row of `table` into `out` (not committed).
void WriteSetpointRows(const interp::SetpointTable& table, SetpointWriter* out);

// The machine's axis names, in order: the columns after `t`.
std::vector<std::string> AxisNames(const Machine& machine);

// Axis positions between the planner's units (mm, rad) and the files' (mm, deg).
class FileUnits {
 public:
  explicit FileUnits(const Machine& machine);
  void FromPlanner(const AxisVector& q, double* out) const;  // one value per axis
  AxisVector ToPlanner(const std::vector<double>& values) const;

 private:
  std::vector<bool> rotary_;
};

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
  FileUnits units_;
  std::vector<double> s_;
  std::vector<interp::LimiterId> limiters_;
  double period_;
};

}  // namespace dtis::io
