#include "dtis/io/gcode.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>
#include <utility>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "rs274.hpp"

namespace dtis::io {
namespace {

// The state a block leaves for the next ones (RS274/NGC modal groups that matter here).
struct Modal {
  GcodeMove::Kind motion = GcodeMove::Kind::kRapid;
  bool motion_set = false;
  bool incremental = false;
  double to_mm = 1.0;  // G21; 25.4 after G20
  double feed_mm_min = 0.0;
  // Where the machine is (offsets applied: the machine frame), mm and degrees.
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  std::array<double, 3> rotary{};
  int system = 1;  // G54
};

// A parameter's value, LinuxCNC's default 0 when not given.
double Parameter(const std::map<int, double>& parameters, int number) {
  const auto it = parameters.find(number);
  return it == parameters.end() ? 0.0 : it->second;
}

struct Word {
  char letter;
  double value;
  int column;  // 1-based
};

}  // namespace

// One block at a time: the modal state, and the move the last block made (at most one).
class GcodeReader::Blocks {
 public:
  Blocks(std::string name, const GcodeStart& start) : file_(std::move(name)) {
    modal_.position = start.tip;
    modal_.rotary = start.rotary;
    const auto& p = start.parameters;
    if (const auto it = p.find(kCoordinateSystemParameter); it != p.end()) {
      if (!(it->second >= 1 && it->second <= 9 && it->second == std::round(it->second))) {
        throw Error(
            "{}: parameter {} (the coordinate system in force) is {}; expected 1 (G54) "
            "to 9 (G59.3)",
            file_, kCoordinateSystemParameter, it->second);
      }
      modal_.system = static_cast<int>(it->second);
    }
    for (int n = 1; n <= 9; ++n) {
      for (std::size_t k = 0; k < 6; ++k) {
        offsets_[static_cast<std::size_t>(n - 1)][k] =
            Parameter(p, WorkOffsetParameter(n) + static_cast<int>(k));
      }
      if (const double r = Parameter(p, WorkOffsetParameter(n) + 9); r != 0.0) {
        throw Error(
            "{}: {} turns the program {} degrees about Z (parameter {}): dtis' own reader does "
            "not turn work offsets; read the program with LinuxCNC's interpreter (interpreter = "
            "\"rs274ngc\" in the job's [path])",
            file_, CoordinateSystemName(n), r, WorkOffsetParameter(n) + 9);
      }
    }
    // G92, kept by LinuxCNC in parameters 5211 … while 5210 is 1.
    if (Parameter(p, 5210) == 1.0) {
      for (std::size_t k = 0; k < 6; ++k) g92_[k] = Parameter(p, 5211 + static_cast<int>(k));
    }
  }

  // Returns false after M2/M30 (the program's end: later lines are not read).
  bool Line(std::string_view text, int line) {
    line_ = line;
    words_.clear();
    if (!Words(text, &words_)) return true;
    return Block(words_);
  }
  // The move of the last block, if it made one (once).
  std::optional<GcodeMove> TakeMove() { return std::exchange(move_, std::nullopt); }
  const std::string& File() const { return file_; }
  const std::array<bool, 3>& UsesRotary() const { return uses_rotary_; }

 private:
  [[noreturn]] void Fail(int column, const std::string& what) const {
    throw Error("{}:{}:{}: {}", file_, line_, column, what);
  }

  // Splits a line into words, dropping comments. Returns false for an empty block.
  bool Words(std::string_view text, std::vector<Word>* words) {
    std::size_t i = 0;
    const std::size_t n = text.size();
    bool only_percent = true;
    while (i < n) {
      const char c = text[i];
      if (c == '(') {
        const std::size_t close = text.find(')', i);
        if (close == std::string_view::npos) Fail(static_cast<int>(i) + 1, "unclosed comment '('");
        i = close + 1;
        continue;
      }
      if (c == ';') break;
      if (std::isspace(static_cast<unsigned char>(c))) {
        ++i;
        continue;
      }
      if (c == '%') {
        ++i;
        continue;
      }
      only_percent = false;
      const int column = static_cast<int>(i) + 1;
      const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      if (!std::isalpha(static_cast<unsigned char>(c))) {
        Fail(column, fmt::format("expected a word (a letter and a number), got '{}'", c));
      }
      if (letter == 'O') {
        Fail(column,
             "O-words (subroutines, loops, conditionals) are not read by dtis' reader; read the "
             "program with LinuxCNC's interpreter (interpreter = \"rs274ngc\" in the job's "
             "[path])");
      }
      ++i;
      while (i < n && (text[i] == ' ' || text[i] == '\t')) ++i;
      // A number: [+-] digits [. digits], NGC style (".5", "5.", "-0.25").
      std::size_t start = i;
      if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
      while (i < n && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
      std::string_view number = text.substr(start, i - start);
      if (!number.empty() && number.front() == '+') number.remove_prefix(1);
      double value = 0.0;
      const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
      if (number.empty() || ec != std::errc() || end != number.data() + number.size() ||
          !std::isfinite(value)) {
        Fail(column, fmt::format("word '{}' needs a number", letter));
      }
      // "X1e300": G-code numbers have no exponent; the E would read as a word of its own.
      if (i + 1 < n && (text[i] == 'e' || text[i] == 'E') &&
          (std::isdigit(static_cast<unsigned char>(text[i + 1])) || text[i + 1] == '-' ||
           text[i + 1] == '+')) {
        std::size_t end_of_exponent = i + 2;
        while (end_of_exponent < n &&
               std::isdigit(static_cast<unsigned char>(text[end_of_exponent])))
          ++end_of_exponent;
        Fail(column, fmt::format("word '{}{}': G-code numbers have no exponent (write the number "
                                 "out in full)",
                                 letter, text.substr(start, end_of_exponent - start)));
      }
      words->push_back({letter, value, column});
    }
    return !words->empty() && !only_percent;
  }

  static bool IsCode(double value, double code) { return std::abs(value - code) < 1e-9; }
  // G54 … G59, G59.1 … G59.3: 1 … 9; 0 for any other code.
  static int CoordinateSystem(double code) {
    for (int n = 1; n <= 9; ++n) {
      if (IsCode(code, n <= 6 ? 53.0 + n : 59.0 + 0.1 * (n - 6))) return n;
    }
    return 0;
  }
  // The offset of axis k (X Y Z A B C) in force: the work offset's and G92's, mm or degrees.
  double Offset(std::size_t k) const {
    return offsets_[static_cast<std::size_t>(modal_.system - 1)][k] + g92_[k];
  }

  bool Block(const std::vector<Word>& words) {
    std::optional<GcodeMove::Kind> motion;
    std::array<std::optional<double>, 6> axis{};  // X Y Z A B C as written
    std::optional<double> i_word, j_word, r_word;
    int motion_column = 0, first_axis_column = 0;
    bool end = false;
    for (const Word& w : words) {
      switch (w.letter) {
        case 'G':
          if (IsCode(w.value, 0)) {
            motion = GcodeMove::Kind::kRapid, motion_column = w.column;
          } else if (IsCode(w.value, 1)) {
            motion = GcodeMove::Kind::kLinear, motion_column = w.column;
          } else if (IsCode(w.value, 2)) {
            motion = GcodeMove::Kind::kArcCw, motion_column = w.column;
          } else if (IsCode(w.value, 3)) {
            motion = GcodeMove::Kind::kArcCcw, motion_column = w.column;
          } else if (IsCode(w.value, 20)) {
            modal_.to_mm = 25.4;
          } else if (IsCode(w.value, 21)) {
            modal_.to_mm = 1.0;
          } else if (IsCode(w.value, 90)) {
            modal_.incremental = false;
          } else if (IsCode(w.value, 91)) {
            modal_.incremental = true;
          } else if (IsCode(w.value, 17) || IsCode(w.value, 94) || IsCode(w.value, 40) ||
                     IsCode(w.value, 49) || IsCode(w.value, 80)) {
            // XY plane, feed per minute, compensation and canned-cycle cancels: nothing to do.
          } else if (const int system = CoordinateSystem(w.value); system > 0) {
            modal_.system = system;
          } else {
            Fail(w.column, fmt::format("G{} is not supported (supported: G0 G1 G2 G3 G17 G20 G21 "
                                       "G40 G49 G54-G59.3 G80 G90 G91 G94)",
                                       w.value));
          }
          break;
        case 'M':
          if (IsCode(w.value, 2) || IsCode(w.value, 30)) {
            end = true;
          } else if (!(IsCode(w.value, 3) || IsCode(w.value, 4) || IsCode(w.value, 5) ||
                       IsCode(w.value, 6) || IsCode(w.value, 7) || IsCode(w.value, 8) ||
                       IsCode(w.value, 9))) {
            Fail(w.column, fmt::format("M{} is not supported (supported: M2 M3 M4 M5 M6 M7 M8 M9 "
                                       "M30)",
                                       w.value));
          }
          break;
        case 'F':
          if (!(w.value > 0.0)) {
            Fail(w.column, fmt::format("feed F must be positive, got {}", w.value));
          }
          modal_.feed_mm_min = w.value * modal_.to_mm;
          break;
        case 'N':
        case 'S':
        case 'T':
          break;
        case 'X':
        case 'Y':
        case 'Z':
        case 'A':
        case 'B':
        case 'C': {
          static constexpr char kAxes[] = "XYZABC";
          const auto k = static_cast<std::size_t>(std::string_view(kAxes).find(w.letter));
          if (axis[k]) Fail(w.column, fmt::format("{} appears twice in the block", w.letter));
          axis[k] = w.value;
          if (!first_axis_column) first_axis_column = w.column;
          break;
        }
        case 'I':
          i_word = w.value;
          break;
        case 'J':
          j_word = w.value;
          break;
        case 'R':
          r_word = w.value;
          break;
        default:
          Fail(w.column, fmt::format("word '{}' is not supported", w.letter));
      }
    }
    if (motion) modal_.motion = *motion, modal_.motion_set = true;
    const bool moves =
        std::any_of(axis.begin(), axis.end(), [](const auto& a) { return a.has_value(); });
    if ((i_word || j_word || r_word) && !moves) {
      Fail(motion_column ? motion_column : 1, "I, J or R without an axis word to move to");
    }
    if (moves) {
      if (!modal_.motion_set) {
        Fail(first_axis_column, "an axis word before any motion mode (G0, G1, G2, G3)");
      }
      Move(axis, i_word, j_word, r_word, motion_column ? motion_column : first_axis_column);
    }
    return !end;
  }

  void Move(const std::array<std::optional<double>, 6>& axis, std::optional<double> i_word,
            std::optional<double> j_word, std::optional<double> r_word, int column) {
    GcodeMove m;
    m.kind = modal_.motion;
    m.line = line_;
    Eigen::Vector3d to = modal_.position;
    for (int k = 0; k < 3; ++k) {
      if (!axis[static_cast<std::size_t>(k)]) continue;
      const double v = *axis[static_cast<std::size_t>(k)] * modal_.to_mm;
      to[k] = modal_.incremental ? to[k] + v : v + Offset(static_cast<std::size_t>(k));
    }
    std::array<double, 3> rotary = modal_.rotary;
    for (int k = 0; k < 3; ++k) {
      const auto& w = axis[static_cast<std::size_t>(k + 3)];
      if (!w) continue;
      rotary[static_cast<std::size_t>(k)] = modal_.incremental
                                                ? rotary[static_cast<std::size_t>(k)] + *w
                                                : *w + Offset(static_cast<std::size_t>(k + 3));
      uses_rotary_[static_cast<std::size_t>(k)] = true;
    }
    m.to = to;
    m.rotary = rotary;
    if (m.kind != GcodeMove::Kind::kRapid) {
      if (!(modal_.feed_mm_min > 0.0)) Fail(column, "a feed move before any feed F was given");
      m.feed_mm_min = modal_.feed_mm_min;
    }
    if (m.kind == GcodeMove::Kind::kArcCw || m.kind == GcodeMove::Kind::kArcCcw) {
      Arc(&m, i_word, j_word, r_word, column);
    } else if (i_word || j_word || r_word) {
      Fail(column, "I, J or R on a straight move");
    }
    modal_.position = to;
    modal_.rotary = rotary;
    move_ = m;
  }

  void Arc(GcodeMove* m, std::optional<double> i_word, std::optional<double> j_word,
           std::optional<double> r_word, int column) {
    const Eigen::Vector2d from = modal_.position.head<2>(), to = m->to.head<2>();
    Eigen::Vector2d center;
    if (r_word) {
      if (i_word || j_word) Fail(column, "an arc takes I/J or R, not both");
      const double r = std::abs(*r_word) * modal_.to_mm;
      const Eigen::Vector2d chord = to - from;
      const double c = chord.norm();
      if (!(c > 0.0)) Fail(column, "an R arc needs distinct start and end points");
      if (c > 2.0 * r * (1.0 + 1e-9)) {
        Fail(column, fmt::format("arc radius {} mm is less than half the chord ({} mm)", r, c / 2));
      }
      const double h = std::sqrt(std::max(0.0, r * r - c * c / 4.0));
      const Eigen::Vector2d mid = 0.5 * (from + to), left(-chord.y() / c, chord.x() / c);
      // The short arc for R > 0, the long one for R < 0; counter-clockwise arcs turn left.
      const bool ccw = m->kind == GcodeMove::Kind::kArcCcw;
      const double side = ((*r_word > 0.0) == ccw) ? 1.0 : -1.0;
      center = mid + left * (side * h);
    } else {
      if (!i_word && !j_word) Fail(column, "an arc (G2/G3) needs I and/or J, or R");
      center = from + Eigen::Vector2d(i_word.value_or(0.0), j_word.value_or(0.0)) * modal_.to_mm;
      const double r0 = (from - center).norm(), r1 = (to - center).norm();
      // LinuxCNC's own check: the end radius may differ by 0.002 mm (or 0.1 % of it).
      if (std::abs(r0 - r1) > std::max(0.002, 1e-3 * r0)) {
        Fail(column,
             fmt::format("arc radius mismatch: {:.6g} mm at the start, {:.6g} mm at the end", r0,
                         r1));
      }
      if (!(r0 > 0.0)) Fail(column, "an arc of zero radius");
    }
    m->center = Eigen::Vector3d(center.x(), center.y(), modal_.position.z());
  }

  std::string file_;
  Modal modal_;
  std::array<std::array<double, 6>, 9> offsets_{};  // G54 … G59.3: X Y Z (mm) A B C (deg)
  std::array<double, 6> g92_{};
  int line_ = 0;
  std::vector<Word> words_;
  std::optional<GcodeMove> move_;
  std::array<bool, 3> uses_rotary_{};
};

std::string TooManyBlocks(const std::string& file, long line, const GcodeReadOptions& options) {
  return fmt::format(
      "{}:{}: the program runs more than {} blocks (each repetition of a loop counted), the most "
      "it may run here{}",
      file, line, options.max_blocks, options.remedy.empty() ? "" : "; " + options.remedy);
}

GcodeReader::GcodeReader(const std::string& path, GcodeInterpreter interpreter,
                         std::shared_ptr<const ToolTable> tools, Cancel* cancel,
                         const GcodeStart& start, const GcodeReadOptions& options)
    : options_(options),
      blocks_(interpreter == GcodeInterpreter::kRs274ngc ? nullptr
                                                         : std::make_unique<Blocks>(path, start)) {
  if (interpreter == GcodeInterpreter::kRs274ngc) {
    rs274_ = std::make_unique<Rs274Reader>(path, std::move(tools), cancel, start, options);
    return;
  }
  if (tools) {
    throw Error(
        "{}: tool length offsets from {} are applied by LinuxCNC's interpreter "
        "(interpreter = \"rs274ngc\"); dtis' own reader plans the programmed tip",
        path, tools->file);
  }
  RequireRegularFile(path);
  in_ = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*in_) throw Error("{}: cannot open the G-code file", path);
}

GcodeReader::GcodeReader(std::string_view text, const std::string& source_name,
                         const GcodeStart& start, const GcodeReadOptions& options)
    : options_(options), blocks_(std::make_unique<Blocks>(source_name, start)), text_(text) {}

GcodeReader::~GcodeReader() = default;

const std::string& GcodeReader::File() const { return rs274_ ? rs274_->File() : blocks_->File(); }
const std::array<bool, 3>& GcodeReader::UsesRotary() const {
  return rs274_ ? rs274_->UsesRotary() : blocks_->UsesRotary();
}

const std::vector<std::pair<std::string, int>>& GcodeReader::Notes() const {
  static const std::vector<std::pair<std::string, int>> kNone;
  return rs274_ ? rs274_->Notes() : kNone;
}

std::optional<GcodeMove> GcodeReader::Next() {
  if (rs274_) return rs274_->Next();
  while (!ended_) {
    std::string_view l;
    if (in_) {
      if (!std::getline(*in_, line_text_)) break;
      l = line_text_;
    } else {
      if (offset_ > text_.size()) break;
      const std::size_t end = text_.find('\n', offset_);
      l = text_.substr(offset_,
                       end == std::string_view::npos ? text_.size() - offset_ : end - offset_);
      offset_ = end == std::string_view::npos ? text_.size() + 1 : end + 1;
    }
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    // Lines with something on them count (a text's last newline ends no empty block).
    if (!l.empty() && options_.max_blocks > 0 && ++blocks_read_ > options_.max_blocks) {
      ended_ = true;
      throw Error("{}", TooManyBlocks(File(), line_ + 1, options_));
    }
    if (!blocks_->Line(l, ++line_)) ended_ = true;
    if (std::optional<GcodeMove> move = blocks_->TakeMove()) return move;
  }
  ended_ = true;
  return std::nullopt;
}

namespace {

// `Reader`: a GcodeReader or an Rs274Reader.
template <typename Reader>
GcodeProgram ReadAll(Reader& reader) {
  GcodeProgram program;
  program.file = reader.File();
  while (auto move = reader.Next()) program.moves.push_back(*move);
  program.uses_rotary = reader.UsesRotary();
  program.notes = reader.Notes();
  return program;
}

}  // namespace

GcodeProgram ParseGcode(std::string_view text, const std::string& source_name,
                        const GcodeStart& start, const GcodeReadOptions& options) {
  GcodeReader reader(text, source_name, start, options);
  return ReadAll(reader);
}

GcodeProgram ParseRs274Records(std::string_view records, const std::string& source_name) {
  Rs274Reader reader(records, source_name);
  return ReadAll(reader);
}

GcodeProgram ReadGcode(const std::string& path, GcodeInterpreter interpreter,
                       std::shared_ptr<const ToolTable> tools, const GcodeStart& start,
                       const GcodeReadOptions& options) {
  GcodeReader reader(path, interpreter, std::move(tools), nullptr, start, options);
  return ReadAll(reader);
}

std::string CoordinateSystemName(int system) {
  return system <= 6 ? fmt::format("G{}", 53 + system) : fmt::format("G59.{}", system - 6);
}

std::map<int, double> ParseParameters(std::string_view text, const std::string& source_name) {
  std::map<int, double> parameters;
  int line = 0;
  for (std::size_t at = 0; at <= text.size();) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    std::string_view l = text.substr(at, end - at);
    at = end + 1;
    ++line;
    const auto skip = [&l] {
      while (!l.empty() && std::isspace(static_cast<unsigned char>(l.front()))) l.remove_prefix(1);
    };
    skip();
    if (l.empty()) continue;
    int number = 0;
    double value = 0.0;
    auto [p, ec] = std::from_chars(l.data(), l.data() + l.size(), number);
    bool ok = ec == std::errc() && p != l.data() + l.size() &&
              std::isspace(static_cast<unsigned char>(*p));
    if (ok) {
      l.remove_prefix(static_cast<std::size_t>(p - l.data()));
      skip();
      if (!l.empty() && l.front() == '+') l.remove_prefix(1);
      auto [q, ec2] = std::from_chars(l.data(), l.data() + l.size(), value);
      ok = ec2 == std::errc() && std::isfinite(value) &&
           (q == l.data() + l.size() || std::isspace(static_cast<unsigned char>(*q)));
    }
    if (!ok || number < 1) {
      throw Error(
          "{}:{}: expected a parameter number and its value (\"5221 10.5\"), as in LinuxCNC's "
          "parameter file",
          source_name, line);
    }
    parameters[number] = value;
  }
  return parameters;
}

std::map<int, double> ReadParameterFile(const std::string& path) {
  RequireRegularFile(path);
  const std::optional<std::string> text = ReadFileText(path);
  if (!text) throw Error("{}: cannot open the parameter file; check the path", path);
  return ParseParameters(*text, path);
}

}  // namespace dtis::io
