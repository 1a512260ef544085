// The independent verifier of a setpoint sequence: per axis, the largest |v|, |a|, |j| from the
// backward differences of Beudaert 2012 (Eq. 6 and 14) as a ratio to the limit, whether the
// sequence starts and ends at rest, and its motion time. It reads positions as written (mm, deg)
// and shares nothing with the planner but the machine's limits.
#pragma once

#include <string>
#include <vector>

#include "dtis/core/machine.hpp"

namespace dtis::interp {

// Setpoints as stored in a file: time in s, then one column per axis in file units (mm, deg).
struct SetpointTable {
  std::vector<std::string> axes;
  std::vector<double> t;
  std::vector<std::vector<double>> columns;  // columns[axis][row]
  std::size_t Rows() const { return t.size(); }
  // Adds a row: one value per column.
  void Append(double time, const double* values) {
    t.push_back(time);
    for (std::size_t i = 0; i < columns.size(); ++i) columns[i].push_back(values[i]);
  }
};

struct AxisCheck {
  std::string name;
  double v = 0.0, a = 0.0, j = 0.0;                    // largest magnitudes, file units per s^k
  double v_ratio = 0.0, a_ratio = 0.0, j_ratio = 0.0;  // to the limits
  long v_row = 0, a_row = 0, j_row = 0;                // where
  // Jerk chatter: the periods whose jerk has the other sign than the period before's, both beyond
  // half the limit (a bang-bang of the axis' jerk from one period to the next, which excites a
  // machine's resonances; a planned reversal passes through smaller jerks).
  long jerk_flips = 0;
};

struct VerifyReport {
  double period_s = 0.0;
  long rows = 0;
  bool uniform_period = true;  // every t_k = t_0 + k dt within 1e-9 s
  long bad_period_row = -1;
  double motion_time_s = 0.0;  // from the last row before the first move to the last move
  bool starts_at_rest = true;  // holding the first row before the file respects every limit
  bool ends_at_rest = true;    // the last three rows are equal: v = a = 0 at the end
  std::vector<AxisCheck> axes;
  double worst_ratio = 0.0;
  std::string worst;  // "X jerk at t = 0.123 s"
  bool Passed() const {
    return uniform_period && starts_at_rest && ends_at_rest && worst_ratio <= 1.0;
  }
};

// Throws dtis::Error if the table's axes are not the machine's (names and order) or the table has
// fewer than 2 rows.
VerifyReport Verify(const SetpointTable& table, const Machine& machine);

// The same checks on rows as they come, in constant memory (a stream fed to a machine). Rows are in
// file units (mm, deg); their times must be t0 + k * period_s.
class StreamVerifier {
 public:
  StreamVerifier(const Machine& machine, double period_s);
  void Add(double t, const double* row);  // one value per axis
  long Rows() const { return rows_; }
  // The report so far, as if the stream ended with the last row (which Verify holds twice more).
  // Throws dtis::Error when fewer than 2 rows were added.
  VerifyReport Report() const;

 private:
  struct AxisState {
    double vmax, amax, jmax;  // file units
    double x[4];              // newest first
    double last_jerk = 0.0;   // the period before's, file units
    AxisCheck check;
  };
  bool Differences(long row, AxisState* a) const;
  double dt_;
  double t0_ = 0.0, last_t_ = 0.0;
  long rows_ = 0;
  long first_move_ = -1, last_move_ = -1;
  bool uniform_ = true, starts_at_rest_ = true;
  long bad_period_row_ = -1;
  std::vector<AxisState> axes_;
};

// A human-readable report, one line per axis.
std::string FormatReport(const VerifyReport& report);

}  // namespace dtis::interp
