#include "dtis/io/setpoint_file.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"

namespace dtis::io {
namespace {

// The lines of a text, '\r\n' or '\n' ended, numbered from 1.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  bool Next(std::string_view* out) {
    if (pos_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    *out = text_.substr(pos_, end - pos_);
    if (!out->empty() && out->back() == '\r') out->remove_suffix(1);
    pos_ = end + 1;
    ++number_;
    return true;
  }
  long Number() const { return number_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  long number_ = 0;
};

std::vector<std::string_view> SplitCommas(std::string_view line) {
  std::vector<std::string_view> fields;
  for (std::size_t start = 0;;) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string_view::npos ? comma : comma - start));
    if (comma == std::string_view::npos) return fields;
    start = comma + 1;
  }
}

constexpr std::string_view kLimiterHeader = "t,s,feed,limiter,axis";

}  // namespace

interp::SetpointTable ParseSetpoints(std::string_view text, const std::string& source) {
  interp::SetpointTable table;
  Lines lines(text);
  std::string_view header;
  if (!lines.Next(&header)) throw Error("{}: empty file; expected a header 't,X,Y,Z...'", source);
  std::vector<std::string> names;
  for (std::string_view name : SplitCommas(header)) names.emplace_back(name);
  if (names.size() < 2 || names[0] != "t") {
    throw Error("{}:1: header must start with 't' then the axis names, got '{}'", source, header);
  }
  for (std::size_t i = 1; i < names.size(); ++i) {
    if (names[i].empty()) throw Error("{}:1: column {} of the header has no name", source, i + 1);
  }
  table.axes.assign(names.begin() + 1, names.end());
  table.columns.resize(table.axes.size());
  std::string_view row;
  while (lines.Next(&row)) {
    const long line = lines.Number();
    if (row.empty()) continue;
    std::size_t column = 0;
    const char* p = row.data();
    const char* end = row.data() + row.size();
    while (true) {
      double value = 0.0;
      const auto [ptr, ec] = std::from_chars(p, end, value);
      if (ec != std::errc() || !std::isfinite(value)) {
        throw Error("{}:{}: column {} ('{}') is not a finite number", source, line, column + 1,
                    names[std::min(column, names.size() - 1)]);
      }
      if (column >= names.size()) {
        throw Error("{}:{}: {} values or more; the header has {} columns", source, line, column + 1,
                    names.size());
      }
      if (column == 0) {
        table.t.push_back(value);
      } else {
        table.columns[column - 1].push_back(value);
      }
      ++column;
      p = ptr;
      if (p == end) break;
      if (*p != ',') {
        throw Error("{}:{}: unexpected character '{}' after column {}", source, line, *p, column);
      }
      ++p;
    }
    if (column != names.size()) {
      throw Error("{}:{}: {} values; the header has {} columns", source, line, column,
                  names.size());
    }
  }
  if (table.t.empty()) throw Error("{}: no setpoint rows after the header", source);
  return table;
}

interp::SetpointTable ReadSetpoints(const std::string& path) {
  const std::optional<std::string> text = ReadFileText(path);
  if (!text) throw Error("{}: cannot open the setpoint file; check the path", path);
  return ParseSetpoints(*text, path);
}

std::vector<interp::LimiterId> ParseLimiters(std::string_view text, const std::string& source,
                                             const std::vector<std::string>& axes) {
  Lines lines(text);
  std::string_view row;
  if (!lines.Next(&row)) {
    throw Error("{}: empty file; expected a limiter report '{}'", source, kLimiterHeader);
  }
  if (row != kLimiterHeader) {
    throw Error("{}:1: expected the header '{}' of a limiter report (dtis run --limiters)", source,
                kLimiterHeader);
  }
  std::vector<interp::LimiterId> limiters;
  while (lines.Next(&row)) {
    const long line = lines.Number();
    if (row.empty()) continue;
    const std::vector<std::string_view> fields = SplitCommas(row);
    if (fields.size() != 5) {
      throw Error("{}:{}: {} values; expected 5 (t,s,feed,limiter,axis)", source, line,
                  fields.size());
    }
    for (std::size_t c = 0; c < 3; ++c) {
      double value = 0.0;
      const auto [ptr, ec] =
          std::from_chars(fields[c].data(), fields[c].data() + fields[c].size(), value);
      if (ec != std::errc() || ptr != fields[c].data() + fields[c].size() ||
          !std::isfinite(value)) {
        constexpr const char* kNames[] = {"t", "s", "feed"};
        throw Error("{}:{}: column {} ('{}') is not a finite number", source, line, c + 1,
                    kNames[c]);
      }
    }
    interp::LimiterId id;
    const auto kind = interp::LimiterFromName(fields[3]);
    if (!kind) throw Error("{}:{}: column 4: unknown limiter '{}'", source, line, fields[3]);
    id.kind = *kind;
    if (!fields[4].empty()) {
      const auto at = std::find(axes.begin(), axes.end(), fields[4]);
      if (at == axes.end()) {
        throw Error("{}:{}: column 5: '{}' is not an axis of the machine", source, line, fields[4]);
      }
      id.axis = static_cast<std::int8_t>(at - axes.begin());
    }
    limiters.push_back(id);
  }
  return limiters;
}

std::string FormatLimiters(const interp::SetpointTable& table,
                           const std::vector<double>& arc_length,
                           const std::vector<interp::LimiterId>& limiters, double period_s) {
  fmt::memory_buffer buf;
  fmt::format_to(std::back_inserter(buf), "{}\n", kLimiterHeader);
  for (std::size_t k = 0; k < limiters.size(); ++k) {
    // Each segment (a pass, a link) counts its arc length from 0, starting at rest where the one
    // before ended.
    const double step = k == 0                              ? 0.0
                        : arc_length[k] < arc_length[k - 1] ? arc_length[k]
                                                            : arc_length[k] - arc_length[k - 1];
    const double feed = step / period_s;
    const auto& l = limiters[k];
    const std::string axis =
        l.axis >= 0 ? table.axes[static_cast<std::size_t>(l.axis)] : std::string();
    fmt::format_to(std::back_inserter(buf), "{},{},{},{},{}\n", table.t[k], arc_length[k], feed,
                   interp::LimiterName(l.kind), axis);
  }
  return {buf.data(), buf.size()};
}

std::vector<interp::LimiterId> ReadLimiters(const std::string& path,
                                            const std::vector<std::string>& axes) {
  const std::optional<std::string> text = ReadFileText(path);
  if (!text) throw Error("{}: cannot open the limiter report; check the path", path);
  return ParseLimiters(*text, path, axes);
}

void WriteSetpointRows(const interp::SetpointTable& table, SetpointWriter* out) {
  std::vector<double> row(table.axes.size());
  for (std::size_t r = 0; r < table.Rows(); ++r) {
    for (std::size_t i = 0; i < row.size(); ++i) row[i] = table.columns[i][r];
    out->Row(table.t[r], row.data());
  }
}

void WriteSetpoints(const std::string& path, const interp::SetpointTable& table) {
  SetpointWriter out(path, table.axes);
  WriteSetpointRows(table, &out);
  out.Commit();
}

SetpointWriter::SetpointWriter(const std::string& path, const std::vector<std::string>& axes)
    : file_(path), axes_(axes.size()) {
  buffer_ = "t";
  for (const auto& a : axes) buffer_ += "," + a;
  buffer_ += '\n';
}

void SetpointWriter::Row(double t, const double* values) {
  fmt::format_to(std::back_inserter(buffer_), "{}", t);
  for (std::size_t i = 0; i < axes_; ++i)
    fmt::format_to(std::back_inserter(buffer_), ",{}", values[i]);
  buffer_ += '\n';
  if (buffer_.size() > (1u << 16)) {
    file_.Write(buffer_);
    buffer_.clear();
  }
}

AtomicFile& SetpointWriter::Finish() {
  file_.Write(buffer_);
  buffer_.clear();
  return file_;
}

void SetpointWriter::Commit() { Finish().Commit(); }

std::vector<std::string> AxisNames(const Machine& machine) {
  std::vector<std::string> names;
  for (const Axis& a : machine.Axes()) names.push_back(a.name);
  return names;
}

FileUnits::FileUnits(const Machine& machine) {
  for (const Axis& a : machine.Axes()) rotary_.push_back(a.rotary);
}

void FileUnits::FromPlanner(const AxisVector& q, double* out) const {
  for (std::size_t i = 0; i < rotary_.size(); ++i) {
    const double v = q[static_cast<Eigen::Index>(i)];
    out[i] = rotary_[i] ? v * (180.0 / std::numbers::pi) : v;
  }
}

AxisVector FileUnits::ToPlanner(const std::vector<double>& values) const {
  AxisVector q(static_cast<Eigen::Index>(rotary_.size()));
  for (std::size_t i = 0; i < rotary_.size(); ++i) {
    q[static_cast<Eigen::Index>(i)] =
        rotary_[i] ? values[i] * (std::numbers::pi / 180.0) : values[i];
  }
  return q;
}

TableSink::TableSink(const Machine& machine, double period_s) : units_(machine), period_(period_s) {
  table_.axes = AxisNames(machine);
  table_.columns.resize(table_.axes.size());
}

void TableSink::Accept(const interp::Setpoint& sp) {
  double row[kMaxAxes];
  units_.FromPlanner(sp.q, row);
  table_.Append(static_cast<double>(sp.index) * period_, row);
  s_.push_back(sp.s);
  limiters_.push_back(sp.limiter);
}

}  // namespace dtis::io
