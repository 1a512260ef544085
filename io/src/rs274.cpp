#include "rs274.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string_view>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"

extern char** environ;

namespace dtis::io {
namespace {

// The words of a record after its kind: numbers, or a number and the rest of the line as text.
class Fields {
 public:
  explicit Fields(std::string_view text) : text_(text) {}
  bool Number(double* value) {
    Skip();
    const auto [end, ec] = std::from_chars(text_.data(), text_.data() + text_.size(), *value);
    if (ec != std::errc() || !std::isfinite(*value)) return false;
    text_.remove_prefix(static_cast<std::size_t>(end - text_.data()));
    return true;
  }
  bool Integer(long* value) {
    Skip();
    const auto [end, ec] = std::from_chars(text_.data(), text_.data() + text_.size(), *value);
    if (ec != std::errc()) return false;
    text_.remove_prefix(static_cast<std::size_t>(end - text_.data()));
    return true;
  }
  std::string_view Rest() {
    Skip();
    return text_;
  }
  bool Done() {
    Skip();
    return text_.empty();
  }

 private:
  void Skip() {
    while (!text_.empty() && text_.front() == ' ') text_.remove_prefix(1);
  }
  std::string_view text_;
};

}  // namespace

std::string Rs274Program() {
  if (const char* env = std::getenv("DTIS_RS274"); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path next_to = exe.parent_path() / "dtis-rs274";
    if (std::filesystem::is_regular_file(next_to, ec)) return next_to.string();
  }
#ifdef DTIS_RS274_BUILD_PATH
  if (std::filesystem::is_regular_file(DTIS_RS274_BUILD_PATH, ec)) return DTIS_RS274_BUILD_PATH;
#endif
  return {};
}

GcodeInterpreter DefaultGcodeInterpreter() {
#ifdef DTIS_RS274_BUILD_PATH
  return GcodeInterpreter::kRs274ngc;
#else
  return GcodeInterpreter::kDtis;
#endif
}

const char* GcodeInterpreterName(GcodeInterpreter interpreter) {
  return interpreter == GcodeInterpreter::kRs274ngc ? "rs274ngc" : "dtis";
}

Rs274Reader::Rs274Reader(const std::string& path, std::shared_ptr<const ToolTable> tools,
                         Cancel* cancel, const GcodeStart& start, const GcodeReadOptions& options)
    : file_(path), options_(options) {
  RequireRegularFile(path);
  if (::access(path.c_str(), R_OK) != 0) {
    throw Error("{}: cannot open the G-code file: {}", path, std::strerror(errno));
  }
  const std::string program = Rs274Program();
  if (program.empty()) {
    throw Error(
        "{}: LinuxCNC's G-code interpreter (the dtis-rs274 program) was not found next to dtis; "
        "build dtis with linuxcnc-uspace-dev installed, set DTIS_RS274 to the program, or read "
        "the program with dtis' own reader (interpreter = \"dtis\" in the job's [path])",
        path);
  }
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) {
    throw Error("{}: cannot start {}: {}", path, program, std::strerror(errno));
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDOUT_FILENO);
  // The interpreter's own chatter (missing parameter file, Python) is not the program's.
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  // dtis-rs274 PROGRAM -s X,Y,Z,A,B,C [-p N=V,...] [-n MAX_BLOCKS] [-t TOOL=POCKET,X,Y,Z,A,B,C,U,V,
  // W,D ...]: where the machine is, the parameters, the block budget, and the table as read and
  // checked here.
  std::vector<std::string> args = {
      program, path, "-s",
      fmt::format("{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", start.tip.x(), start.tip.y(),
                  start.tip.z(), start.rotary[0], start.rotary[1], start.rotary[2])};
  if (options.max_blocks > 0) {
    args.push_back("-n");
    args.push_back(std::to_string(options.max_blocks));
  }
  if (!start.parameters.empty()) {
    std::string list;
    for (const auto& [number, value] : start.parameters) {
      list += fmt::format("{}{}={:.17g}", list.empty() ? "" : ",", number, value);
    }
    args.push_back("-p");
    args.push_back(list);
  }
  if (tools) {
    args.push_back("-t");
    for (const ToolEntry& t : tools->tools) {
      std::string arg = fmt::format("{}={}", t.tool, t.pocket);
      for (const double v : t.offset) arg += fmt::format(",{:.17g}", v);
      args.push_back(arg + fmt::format(",{:.17g}", t.diameter));
    }
  }
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const int spawned =
      ::posix_spawn(&pid_, program.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(pipe_fds[1]);
  if (spawned != 0) {
    ::close(pipe_fds[0]);
    pid_ = -1;
    throw Error("{}: cannot start {}: {}", path, program, std::strerror(spawned));
  }
  out_ = ::fdopen(pipe_fds[0], "r");
  if (out_ == nullptr) {
    ::close(pipe_fds[0]);
    Reap();
    throw Error("{}: cannot read {}: {}", path, program, std::strerror(errno));
  }
  kill_on_cancel_ = Cancel::Hook(cancel, [pid = pid_] { ::kill(pid, SIGKILL); });
}

Rs274Reader::Rs274Reader(std::string_view records, const std::string& name)
    : file_(name), text_(records) {}

bool Rs274Reader::NextRecord() {
  record_.clear();
  if (text_) {
    if (text_->empty()) return false;
    const std::size_t end = text_->find('\n');
    record_ = std::string(text_->substr(0, end));
    text_->remove_prefix(end == std::string_view::npos ? text_->size() : end + 1);
    return true;
  }
  char buffer[4096];
  bool got = false;
  while (std::fgets(buffer, sizeof buffer, out_) != nullptr) {
    got = true;
    record_ += buffer;
    if (record_.back() == '\n') break;
  }
  if (!record_.empty() && record_.back() == '\n') record_.pop_back();
  return got;
}

Rs274Reader::~Rs274Reader() {
  kill_on_cancel_.Reset();
  if (pid_ > 0) ::kill(pid_, SIGKILL);
  if (out_ != nullptr) std::fclose(out_);
  if (pid_ > 0) {
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
  }
}

std::string Rs274Reader::Reap() {
  kill_on_cancel_.Reset();  // the pid stays ours until it is reaped
  if (pid_ <= 0) return {};
  int status = 0;
  pid_t done;
  while ((done = ::waitpid(pid_, &status, 0)) < 0 && errno == EINTR) {
  }
  pid_ = -1;
  if (done < 0) return {};
  if (WIFSIGNALED(status)) {
    return fmt::format("LinuxCNC's interpreter (dtis-rs274) died of signal {} ({})",
                       WTERMSIG(status), ::strsignal(WTERMSIG(status)));
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) > 1) {
    return fmt::format("LinuxCNC's interpreter (dtis-rs274) exited with status {}",
                       WEXITSTATUS(status));
  }
  return {};
}

void Rs274Reader::Fail(int line, const std::string& what) {
  ended_ = true;
  Reap();
  throw Error("{}:{}: {}", file_, line, what);
}

void Rs274Reader::BadRecord(const std::string& why) {
  ended_ = true;
  const std::string died = Reap();
  if (!died.empty()) throw Error("{}: {} after {} records", file_, died, records_);
  throw Error("{}: LinuxCNC's interpreter (dtis-rs274) wrote record {} '{}': {}", file_, records_,
              record_.substr(0, 80), why);
}

void Rs274Reader::Note(const std::string& what) {
  for (auto& [text, count] : notes_) {
    if (text == what) {
      ++count;
      return;
    }
  }
  notes_.emplace_back(what, 1);
}

GcodeMove Rs274Reader::Move(int line, GcodeMove::Kind kind, const double* abc) {
  GcodeMove m;
  m.line = line;
  m.kind = kind;
  for (std::size_t k = 0; k < 3; ++k) {
    m.rotary[k] = abc[k];
    if (abc[k] != 0.0) uses_rotary_[k] = true;
  }
  if (kind != GcodeMove::Kind::kRapid) {
    if (!(feed_mm_min_ > 0.0)) {
      // LinuxCNC's interpreter gives G5.2 no feed in inverse time (G93), whatever its F word.
      Fail(line, kind == GcodeMove::Kind::kNurbs
                     ? "a NURBS (G5.2) with no feed rate: LinuxCNC gives none in inverse time "
                       "(G93); program it in G94 with an F word"
                     : "a feed move with no feed rate (program an F word before it)");
    }
    m.feed_mm_min = feed_mm_min_;
  }
  m.tolerance_mm = tolerance_mm_;
  m.stop = stop_;
  m.rest_before = std::exchange(rest_next_, false);
  m.dwell_s = std::exchange(dwell_next_, 0.0);
  return m;
}

std::optional<GcodeMove> Rs274Reader::Next() {
  while (!ended_) {
    if (!NextRecord()) BadRecord("the output ended before the program's end");
    ++records_;
    if (record_ == "X") {
      ended_ = true;
      if (dwell_next_ > 0.0) Note("dwell (G4) after the last move: not held (nothing follows it)");
      const std::string died = Reap();
      if (!died.empty()) throw Error("{}: {}", file_, died);
      return std::nullopt;
    }
    if (record_.size() < 2 || record_[1] != ' ') BadRecord("not a record");
    const char kind = record_[0];
    Fields f(std::string_view(record_).substr(2));
    long line = 0;
    if (!f.Integer(&line) || line < 0 || line > 1'000'000'000) BadRecord("no line number");
    const auto numbers = [&](double* out, int n) {
      for (int k = 0; k < n; ++k) {
        if (!f.Number(&out[k])) BadRecord(fmt::format("expected {} numbers", n));
      }
    };
    switch (kind) {
      case 'E':
        Fail(static_cast<int>(line), std::string(f.Rest()));
      case 'B': {  // the interpreter ran max_blocks blocks and stopped before this one
        ended_ = true;
        Reap();
        throw Error("{}", TooManyBlocks(file_, line, options_));
      }
      case 'I':
        Note(std::string(f.Rest()));
        continue;
      case 'F': {
        double v;
        numbers(&v, 1);
        feed_mm_min_ = v;
        continue;
      }
      case 'P': {
        double v[2];
        numbers(v, 2);
        stop_ = v[0] < 2.5;  // exact stop or exact path: the machine stops at every block's end
        tolerance_mm_ = v[1];
        if (stop_)
          Note(v[0] < 1.5 ? "exact stop (G61.1)" : "exact path (G61): a stop at every corner");
        continue;
      }
      case 'D': {
        double v;
        numbers(&v, 1);
        if (!(v >= 0.0) || v > 1e6) {
          Fail(static_cast<int>(line), fmt::format("a dwell (G4) of {} s: expected 0 to 1e6 s", v));
        }
        rest_next_ = true;
        dwell_next_ += v;
        Note("dwell (G4): held at rest for its time");
        continue;
      }
      case 'T':
      case 'L':
      case 'A': {
        double p[13];
        const int n = kind == 'A' ? 13 : 6;
        numbers(p, n);
        if (!f.Done()) BadRecord("trailing fields");
        GcodeMove m =
            Move(static_cast<int>(line),
                 kind == 'T' ? GcodeMove::Kind::kRapid : GcodeMove::Kind::kLinear, p + n - 3);
        m.to = Eigen::Vector3d(p[0], p[1], p[2]);
        if (kind == 'A') {
          m.center = Eigen::Vector3d(p[3], p[4], p[5]);
          m.normal = Eigen::Vector3d(p[6], p[7], p[8]);
          if (std::abs(m.normal.norm() - 1.0) > 1e-9) BadRecord("the arc's axis is not a unit");
          const double turns = p[9];
          if (turns == 0.0 || std::abs(turns) > 1e6 || turns != std::round(turns)) {
            BadRecord("the arc's turns are not a whole number");
          }
          m.kind = turns > 0.0 ? GcodeMove::Kind::kArcCcw : GcodeMove::Kind::kArcCw;
          m.turns = static_cast<int>(std::abs(turns));
        }
        return m;
      }
      case 'N': {
        // order z a b c count, then x y w per control point (the first: where the move starts).
        double head[6];
        numbers(head, 6);
        const double order = head[0], count = head[5];
        if (order < 2 || order > 16 || order != std::round(order) || count < order || count > 1e7 ||
            count != std::round(count)) {
          BadRecord("a NURBS needs an order from 2 to 16 and at least as many control points");
        }
        auto nurbs = std::make_shared<GcodeMove::Nurbs>();
        nurbs->order = static_cast<int>(order);
        for (long k = 0; k < static_cast<long>(count); ++k) {
          double p[3];
          numbers(p, 3);
          if (!(p[2] > 0.0)) Fail(static_cast<int>(line), "a NURBS weight (P) must be positive");
          nurbs->poles.emplace_back(p[0], p[1], head[1]);
          nurbs->weights.push_back(p[2]);
        }
        if (!f.Done()) BadRecord("trailing fields");
        GcodeMove m = Move(static_cast<int>(line), GcodeMove::Kind::kNurbs, head + 2);
        m.to = nurbs->poles.back();
        m.nurbs = std::move(nurbs);
        return m;
      }
      default:
        BadRecord("unknown record");
    }
  }
  return std::nullopt;
}

}  // namespace dtis::io
