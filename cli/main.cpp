// The dtis command: parse arguments, call the libraries, print the summary and errors.
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>

#include "dtis/core/error.hpp"
#include "dtis/core/version.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/io/atomic_file.hpp"
#include "dtis/io/compare.hpp"
#include "dtis/io/figures.hpp"
#include "dtis/io/hal_stream.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/report.hpp"
#include "dtis/io/serve.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/io/stream.hpp"
#include "dtis/kinematics/machines.hpp"
#include "stop_signals.hpp"

namespace {

// Exit status, the same for every subcommand.
constexpr int kExitBadInput = 1;          // a file, option value or request is wrong: one message
constexpr int kExitUsage = 2;             // the command line itself: unknown option, missing FILE
constexpr int kExitVerifyFailed = 3;      // the setpoints fail the verifier
constexpr int kExitInternal = 4;          // a bug: please report it with the job
constexpr int kExitStreamEndedEarly = 5;  // a stream or job ended before its end, at rest
constexpr const char* kExitStatusHelp =
    "Exit status: 0 ok; 1 bad input (file, option value or request); 2 usage (the command line); "
    "3 the setpoints fail the verifier; 4 internal error; 5 a stream ended early, at rest.\n";

// A progress line on a terminal only (pipes and files stay clean; -q silences it): the phase, and
// while planning a bar by the share of the path planned (it moves within a segment too), the motion
// time planned and the segments finished. Redrawn at most 20 times a second, and at each new phase.
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled && isatty(fileno(stderr))) {}
  ~Progress() { Clear(); }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void Show(const dtis::io::RunProgress& p) {
    if (!enabled_) return;
    std::lock_guard lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    if (p.phase == phase_ && now - last_ < std::chrono::milliseconds(50)) return;
    phase_ = p.phase;
    last_ = now;
    if (p.fraction < 0.0) {
      std::fprintf(stderr, "\r\033[K%.*s ...", static_cast<int>(p.phase.size()), p.phase.data());
    } else {
      constexpr int kWidth = 30;
      const int filled = static_cast<int>(kWidth * p.fraction);
      std::fprintf(stderr, "\r\033[K%.*s [%s%s] %3.0f%%  %.3f s of motion  %d/%d",
                   static_cast<int>(p.phase.size()), p.phase.data(),
                   std::string(filled, '#').c_str(), std::string(kWidth - filled, '.').c_str(),
                   100.0 * p.fraction, p.motion_s, p.segments_done, p.segments);
    }
    std::fflush(stderr);
    shown_ = true;
  }
  void Phase(std::string_view phase) { Show({phase}); }
  void Clear() {
    if (!enabled_ || !shown_) return;
    std::lock_guard lock(mutex_);
    std::fputs("\r\033[K", stderr);
    std::fflush(stderr);
    shown_ = false;
    phase_ = {};
  }

 private:
  bool enabled_;
  bool shown_ = false;
  std::mutex mutex_;
  std::string phase_;
  std::chrono::steady_clock::time_point last_{};
};

// A surface job's face for its report. A face OpenCASCADE cannot mesh costs the report its
// surface, not the run its output: a warning, and the report without it.
std::optional<dtis::geometry::FaceMesh> ReportSurface(const dtis::io::Job& job) {
  if (!job.surface) return std::nullopt;
  try {
    return dtis::io::MeshJobSurface(job);
  } catch (const dtis::Error& e) {
    std::fprintf(stderr, "dtis: warning: the report shows no surface: %s\n", e.what());
    return std::nullopt;
  }
}

// What every report of a planned run shows: its setpoints, their verification, and what decided
// each period.
dtis::io::ReportInput PlannedReport(std::string title, const dtis::Machine& machine,
                                    const dtis::interp::SetpointTable& table,
                                    const dtis::interp::VerifyReport& verify,
                                    std::vector<dtis::interp::LimiterId> limiters,
                                    double compute_s) {
  dtis::io::ReportInput in;
  in.title = std::move(title);
  in.machine = &machine;
  in.table = &table;
  in.verify = &verify;
  in.limiters = std::move(limiters);
  in.compute_s = compute_s;
  return in;
}

// A job's report: `in` with the job's programmed feed, what the job is (before `in`'s own header
// rows) and, for a surface job, its face.
std::string RenderJobReport(const dtis::io::Job& job, dtis::io::ReportInput in,
                            const std::string& plotly) {
  in.programmed_feed_mm_min = job.vpop.feed_mm_s * 60.0;
  std::vector<dtis::io::ReportFact> about = dtis::io::JobFacts(job, *in.machine);
  about.insert(about.end(), in.about.begin(), in.about.end());
  in.about = std::move(about);
  const auto surface = ReportSurface(job);
  if (surface) in.surface = &*surface;
  return dtis::io::RenderReport(in, plotly);
}

// --planner: "vpop", "lookahead" or "least-time" overrides the job's [interpolator] planner (""
// keeps it).
void ApplyPlanner(const std::string& planner, dtis::io::Job* job) {
  if (planner.empty()) return;
  if (job->interpolator != dtis::io::InterpolatorKind::kVpop) {
    throw dtis::Error(
        "--planner {}: {} plans with a Taylor interpolator ([interpolator] kind), "
        "which has no planner to choose",
        planner, job->file);
  }
  job->vpop.planner = *dtis::interp::PlannerFromName(planner);  // CLI11 checked the name
}

// --jerk-time-ms: the job key machine_jerk_time_ms from the command line (0: not given), for a
// LinuxCNC INI machine without MAX_JERK.
void ApplyJerkTime(double ms, dtis::io::Job* job) {
  if (!(ms > 0.0)) return;
  if (!dtis::kinematics::IsLinuxcncIni(job->machine_file)) {
    throw dtis::Error(
        "--jerk-time-ms: only used with a LinuxCNC INI machine; {} (the machine of {}) states "
        "every jerk",
        job->machine_file, job->file);
  }
  job->machine_options.jerk_time_s = ms * 1e-3;
}

// Numeric options: a finite number in range, the message printing the value as given and the
// bounds short (CLI11's PositiveNumber and NonNegativeNumber print their bounds as 309-digit
// numbers and let NaN through).
CLI::Validator NumberCheck(bool zero_allowed) {
  return CLI::Validator(
      [zero_allowed](std::string& input) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(input, v) || !std::isfinite(v) || v < 0.0 ||
            (v == 0.0 && !zero_allowed)) {
          return fmt::format("expected a finite number {} 0, got '{}'", zero_allowed ? ">=" : ">",
                             input);
        }
        return {};
      },
      zero_allowed ? "NONNEGATIVE" : "POSITIVE");
}
const CLI::Validator kPositive = NumberCheck(false);
const CLI::Validator kNonNegative = NumberCheck(true);

const char* const kPlannerHelp =
    "lookahead (the exact step capped by the viable feeds ahead; the default), vpop (the "
    "paper's back-off) or least-time (the look-ahead's plan shortened on the discrete problem; "
    "plans whole, does not stream); overrides the job's [interpolator] planner";

// "X,Y,Z[,A,C]" in machine units (mm, deg), as many values as the machine has axes.
dtis::AxisVector ParseAxisPositions(const std::string& text, const dtis::Machine& machine) {
  std::vector<double> values;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? comma : comma - start);
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(v)) {
      throw dtis::Error("--from: '{}' is not a number; expected {} comma-separated axis positions",
                        item, machine.AxisCount());
    }
    values.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (static_cast<int>(values.size()) != machine.AxisCount()) {
    throw dtis::Error("--from: {} values; machine '{}' has {} axes", values.size(), machine.Name(),
                      machine.AxisCount());
  }
  return dtis::io::FileUnits(machine).ToPlanner(values);
}

struct RunArgs {
  std::string job, output, limiters, report, planner, from;
  bool quiet = false, keep_failed = false;
  int threads = 0;
  long horizon = 0;
  double jerk_time_ms = 0.0;
};

int Run(const RunArgs& a) {
  dtis::io::Job job = dtis::io::LoadJob(a.job);
  if (a.horizon > 0) job.vpop.commit_horizon = static_cast<std::size_t>(a.horizon);
  ApplyPlanner(a.planner, &job);
  ApplyJerkTime(a.jerk_time_ms, &job);
  if (!a.from.empty()) {
    // Where the machine is: a G-code program starts there (the job's [path] from otherwise).
    if (job.surface || job.path.kind != dtis::io::PathSpec::Kind::kGcode) {
      throw dtis::Error(
          "--from: {} is not a G-code job; its path starts where the job says (`dtis stream "
          "--from` leads a link there from where the machine is)",
          job.file);
    }
    const auto machine = dtis::io::LoadJobMachine(job);
    job.path.gcode.from = dtis::io::GcodeFrom(ParseAxisPositions(a.from, *machine), *machine);
  }
  std::string setpoints = !a.output.empty()            ? a.output
                          : !job.setpoints_out.empty() ? job.setpoints_out
                                                       : job.name + ".csv";
  const std::string limiter_file = !a.limiters.empty() ? a.limiters : job.limiters_out;
  const std::string plotly =
      a.report.empty() ? "" : dtis::io::LoadPlotly();  // fail before planning
  Progress progress(!a.quiet);
  dtis::io::RunOptions options;
  options.threads = a.threads;
  options.progress = [&progress](const dtis::io::RunProgress& p) { progress.Show(p); };
  const dtis::io::RunResult result = dtis::io::RunJob(job, options);
  // Setpoints that break a limit never reach a file a machine could be fed from, unless asked
  // for (to study them).
  const bool failed = !dtis::io::FitToWrite(job, result);
  if (failed && !a.keep_failed) {
    progress.Clear();
    if (!a.quiet) std::fputs(dtis::io::FormatRunSummary(job, result).c_str(), stderr);
    std::fprintf(stderr, "dtis: %s: nothing written; --keep-failed writes them anyway\n",
                 dtis::io::UnfitMessage(job, result).c_str());
    return kExitVerifyFailed;
  }
  // The report lands with the setpoints: one written in place (a device, a FIFO) first, since it
  // cannot be taken back, so that a failed write there leaves no setpoints.
  std::optional<dtis::io::AtomicFile> html;
  if (!a.report.empty()) {
    progress.Phase("writing the report");
    dtis::io::ReportInput in = PlannedReport(job.name, *result.machine, result.table, result.verify,
                                             result.limiters, result.compute_s);
    in.passes = result.passes;
    in.pass_rows = result.pass_rows;
    in.unreachable = result.unreachable_all;
    html.emplace(a.report).Write(RenderJobReport(job, std::move(in), plotly));
    if (html->InPlace()) html->Commit();
  }
  progress.Phase("writing");
  dtis::io::WriteRunOutputs(job, result, setpoints, limiter_file, a.keep_failed);
  if (html && !html->InPlace()) html->Commit();
  progress.Clear();
  if (!a.quiet) {
    std::fputs(dtis::io::FormatRunSummary(job, result).c_str(), stderr);
    std::fprintf(stderr, "wrote            %s%s%s%s%s\n", setpoints.c_str(),
                 limiter_file.empty() ? "" : ", ", limiter_file.c_str(),
                 a.report.empty() ? "" : ", ", a.report.c_str());
  }
  return failed ? kExitVerifyFailed : 0;
}

struct CompareArgs {
  std::string job, csv, markdown, exports, report, planner = "both";
  bool quiet = false;
  int threads = 0;
  double jerk_time_ms = 0.0;
};

int Compare(const CompareArgs& a) {
  dtis::io::Job job = dtis::io::LoadJob(a.job);
  ApplyJerkTime(a.jerk_time_ms, &job);
  const std::string plotly =
      a.report.empty() ? "" : dtis::io::LoadPlotly();  // fail before planning
  dtis::io::CompareOptions options;
  options.threads = a.threads;
  options.exports_dir = a.exports;
  if (a.planner == "both") {
    // The job's planner first: its exact variant is the one the report shows in full.
    const auto other = job.vpop.planner == dtis::interp::PlannerKind::kVpop
                           ? dtis::interp::PlannerKind::kLookAhead
                           : dtis::interp::PlannerKind::kVpop;
    options.planners = {job.vpop.planner, other};
  } else {
    ApplyPlanner(a.planner, &job);
    options.planners = {job.vpop.planner};
  }
  Progress progress(!a.quiet);
  options.progress = [&progress](const std::string& variant) {
    progress.Phase("exporting and planning " + variant);
  };
  const dtis::io::CompareResult result = dtis::io::RunCompare(job, options);
  progress.Clear();
  // The tables and the report land together or not at all.
  std::optional<dtis::io::AtomicFile> csv, md, html;
  if (!a.csv.empty()) csv.emplace(a.csv).Write(dtis::io::FormatCompareCsv(result));
  if (!a.markdown.empty()) md.emplace(a.markdown).Write(dtis::io::FormatCompareMarkdown(result));
  if (!a.report.empty()) {
    // The comparison on top; below it, the full report of the exact-surface variant with the
    // job's own axis.
    const auto machine = dtis::io::LoadJobMachine(job);
    const dtis::io::VariantResult& exact = dtis::io::ExactVariantOf(
        result, options.planners.front(),
        job.surface->orientation.axis_tolerance_rad * 180.0 / std::numbers::pi);
    dtis::io::ReportInput in = PlannedReport(job.name + " (compare)", *machine, exact.table,
                                             exact.verify, exact.limiters, exact.compute_s);
    in.passes = result.passes;
    in.pass_rows = exact.pass_rows;
    in.compare = &result;
    in.shown = dtis::io::VariantLabel(exact);
    html.emplace(a.report).Write(RenderJobReport(job, std::move(in), plotly));
  }
  dtis::io::CommitTogether({csv ? &*csv : nullptr, md ? &*md : nullptr, html ? &*html : nullptr});
  std::fputs(dtis::io::FormatCompareText(result).c_str(), stdout);
  for (const auto& v : result.variants) {
    if (!v.verify.Passed()) return kExitVerifyFailed;
  }
  return 0;
}

const std::string kStreamToHelp =
    std::string(
        "output: - for stdout, a file or FIFO (halstreamer's stdin), or hal:N straight into "
        "HAL's streamer.N") +
    (dtis::io::NativeHalBuilt() ? "" : " (hal:N not in this build: no linuxcnc-uspace-dev)");

// Set by a stop signal: a stream then ends with its stop to rest, a daemon shuts down the same
// way.
std::atomic<bool> g_interrupted{false};
std::atomic<int> g_signal{0};

// The stop signals: every signal whose default action ends the process and that can be caught
// (SIGKILL cannot; SIGSTOP and SIGTSTP only suspend it). The ones a fault raises (SIGSEGV,
// SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS, SIGABRT) stop the machine when another process sends
// them, and keep their default action when dtis itself raised them. SIGPIPE is among them
// until a stream or daemon ignores it (a reader gone is then a write error, reported).
struct StopSignals {
  static constexpr int kMax = dtis::cli::kMaxSignal;
  std::array<struct sigaction, kMax> old{};
  std::array<bool, kMax> caught{};
  bool installed = false;
};
StopSignals g_stop_signals;

extern "C" void OnStopSignal(int sig, siginfo_t* info, void* /*context*/) {
  if (dtis::cli::IsFaultSignal(sig) &&
      (info == nullptr || info->si_code > 0 || info->si_pid == getpid())) {
    // A fault of dtis itself (or abort()): its default action, at once.
    struct sigaction fatal {};
    fatal.sa_handler = SIG_DFL;
    sigemptyset(&fatal.sa_mask);
    sigaction(sig, &fatal, nullptr);
    if (info == nullptr || info->si_code <= 0) raise(sig);
    return;  // a hardware fault happens again, now with the default action
  }
  g_signal = sig;
  g_interrupted = true;
}

// Caught before anything else runs: from the executable's .preinit_array, before the shared
// libraries initialise, so that a signal that comes while the program starts or a stream's job
// loads is kept, even where the parent shell ignores SIGINT (as for `cmd &`). Signals the parent
// ignores are caught too: dtis feeds a machine. (While the dynamic loader relocates the libraries,
// before this runs, the launcher keeps them blocked.)
void CatchStopSignals(char** envp) {
  StopSignals& s = g_stop_signals;
  if (s.installed) return;
  s.installed = true;
  struct sigaction stop {};
  stop.sa_sigaction = OnStopSignal;
  stop.sa_flags = SA_SIGINFO;
  sigemptyset(&stop.sa_mask);
  dtis::cli::ForEachStopSignal([&](int sig) {
    if (sig < StopSignals::kMax) s.caught[sig] = sigaction(sig, &stop, &s.old[sig]) == 0;
  });
  // The launcher (`dtis`, cli/launcher.cpp) blocked them while this program's libraries loaded:
  // caught now, they are unblocked, and one that came meanwhile is delivered here. (From the
  // .preinit_array, before the C library sets `environ` up: read from `envp`.)
  const std::string_view name = dtis::cli::kBlockedByLauncher;
  for (char** e = envp; e != nullptr && *e != nullptr; ++e) {
    const std::string_view var = *e;
    if (var.size() <= name.size() || var.substr(0, name.size()) != name ||
        var[name.size()] != '=') {
      continue;
    }
    sigset_t set;
    sigemptyset(&set);
    const char* blocked = *e + name.size() + 1;
    for (char* end = nullptr;; blocked = end + 1) {
      const long sig = std::strtol(blocked, &end, 10);
      if (end == blocked) break;
      if (sig > 0 && sig < StopSignals::kMax && s.caught[sig])
        sigaddset(&set, static_cast<int>(sig));
      if (*end != ',') break;
    }
    sigprocmask(SIG_UNBLOCK, &set, nullptr);
  }
}
extern "C" void DtisCatchStopSignalsFirst(int, char**, char** envp) { CatchStopSignals(envp); }
[[gnu::used, gnu::section(".preinit_array")]] void (*const kCatchStopSignalsFirst)(
    int, char**, char**) = DtisCatchStopSignalsFirst;

// For a stream or a daemon: keep catching them; a reader gone is a write error, reported.
void KeepStopSignals() { std::signal(SIGPIPE, SIG_IGN); }

// Commands that feed no machine get the signals' dispositions back once the command line is
// read, and a signal caught until then takes effect as it would have.
void ReleaseStopSignals() {
  StopSignals& s = g_stop_signals;
  for (int sig = 1; sig < StopSignals::kMax; ++sig) {
    if (s.caught[sig]) sigaction(sig, &s.old[sig], nullptr);
  }
  if (const int sig = g_signal.load(); sig != 0) std::raise(sig);
}

// "SIGQUIT", for messages.
std::string SignalName(int sig) {
  if (sig == SIGRTMIN) return "SIGRTMIN";
  if (sig == SIGRTMAX) return "SIGRTMAX";
  if (sig > SIGRTMIN && sig <= SIGRTMAX) return fmt::format("SIGRTMIN+{}", sig - SIGRTMIN);
  const char* abbrev = sigabbrev_np(sig);
  return abbrev ? fmt::format("SIG{}", abbrev) : fmt::format("signal {}", sig);
}

struct StreamArgs {
  std::string job, to = "-", record, report, pace = "auto", from, planner;
  long buffer = 200, horizon = 0, low_water = 20, slow_planner_us = 0;
  bool index = false, quiet = false;
  double jerk_time_ms = 0.0;
};

// Where a stream goes: "-" (stdout), a file or FIFO (halstreamer's stdin; a FIFO opens when its
// reader does) as halstreamer lines, or "hal:N" straight into HAL's streamer.N.
class StreamOutput {
 public:
  StreamOutput(const std::string& to, const dtis::Machine& machine, bool index, long buffer)
      : to_(to) {
    if (to.rfind("hal:", 0) == 0) {
      const std::string channel = to.substr(4);
      char* end = nullptr;
      const long n = std::strtol(channel.c_str(), &end, 10);
      if (channel.empty() || *end != '\0' || n < 0 || n > 7) {
        throw dtis::Error("--to {}: expected hal:N, N the streamer channel 0..7", to);
      }
      out_ = dtis::io::OpenHalStreamer(static_cast<int>(n), machine.AxisCount(), index, buffer);
      paced_ = true;
      return;
    }
    if (to != "-") {
      file_ = std::fopen(to.c_str(), "w");
      if (!file_)
        throw dtis::Error("{}: cannot open the stream output: {}", to, std::strerror(errno));
    }
    struct stat st {};
    paced_ = fstat(fileno(file_), &st) == 0 && !S_ISREG(st.st_mode);
    out_ = std::make_unique<dtis::io::HalstreamerOutput>(file_, machine.AxisCount(), index);
  }
  ~StreamOutput() {
    if (file_ != stdout) std::fclose(file_);
  }
  StreamOutput(const StreamOutput&) = delete;
  StreamOutput& operator=(const StreamOutput&) = delete;

  dtis::io::CncOutput& Cnc() { return *out_; }
  // Paced by what reads it (a pipe, a FIFO, a terminal, HAL), not a regular file.
  bool Paced() const { return paced_; }
  // Closes a file output, reporting what the last writes could not.
  void Close() {
    if (file_ == stdout) return;
    std::FILE* file = std::exchange(file_, stdout);
    if (std::fclose(file) != 0) {
      throw dtis::Error("{}: cannot close the stream output: {}", to_, std::strerror(errno));
    }
  }

 private:
  std::string to_;
  std::FILE* file_ = stdout;
  std::unique_ptr<dtis::io::CncOutput> out_;
  bool paced_ = false;
};

int Stream(const StreamArgs& a) {
  KeepStopSignals();
  dtis::io::Job job = dtis::io::LoadJob(a.job);
  ApplyPlanner(a.planner, &job);
  ApplyJerkTime(a.jerk_time_ms, &job);
  if (job.vpop.planner == dtis::interp::PlannerKind::kLeastTime) {
    // Before any output is opened: the planner would refuse the stream only once it started.
    throw dtis::Error(
        "{}: [interpolator] planner = \"least-time\" plans a path whole and cannot stream it; "
        "stream with --planner lookahead or vpop",
        job.file);
  }
  const std::string plotly = a.report.empty() ? "" : dtis::io::LoadPlotly();  // fail before moving
  const auto machine = dtis::io::LoadJobMachine(job);
  std::optional<dtis::AxisVector> from;
  if (!a.from.empty()) from = ParseAxisPositions(a.from, *machine);
  const auto segments = dtis::io::JobSegments(job, *machine, from);
  if (const std::string notes = segments->Notes(); !notes.empty()) {
    std::fputs(("unreachable      " + notes).c_str(), stderr);
  }
  std::optional<dtis::io::SetpointWriter> record;
  if (!a.record.empty()) record.emplace(a.record, dtis::io::AxisNames(*machine));
  StreamOutput output(a.to, *machine, a.index, a.buffer);
  dtis::io::StreamOptions o;
  o.period_s = job.vpop.period_s;
  o.buffer_periods = a.buffer;
  o.commit_horizon =
      a.horizon > 0 ? static_cast<std::size_t>(a.horizon) : dtis::io::StreamHorizon(job);
  o.low_water_periods = a.low_water;
  o.realtime = a.pace == "realtime" || (a.pace == "auto" && output.Paced());
  o.slow_planner_us = a.slow_planner_us;
  o.keep_rows = !a.report.empty();
  dtis::io::Stream stream(*machine, o);

  std::atomic<bool> finished{false};
  std::thread watcher([&] {
    while (!finished) {
      if (g_interrupted) {
        stream.Abort();
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  dtis::io::StreamResult r;
  try {
    r = stream.Run(*segments, output.Cnc(), record ? &*record : nullptr);
  } catch (const dtis::Error& e) {
    finished = true;
    watcher.join();
    // The output failed (its reader died): what was sent is recorded, the evidence.
    if (!stream.Recorded()) throw;
    throw dtis::Error("{}; the {} setpoints sent until then are recorded in {}", e.what(),
                      stream.Status().rows.load(), a.record);
  } catch (...) {
    finished = true;
    watcher.join();
    throw;
  }
  finished = true;
  watcher.join();
  output.Close();
  // What the machine was sent, stop included, as the report shows it.
  if (!a.report.empty() && r.rows >= 2) {
    dtis::io::WriteFileAtomically(
        a.report,
        RenderJobReport(
            job,
            PlannedReport(fmt::format("{} (stream, {})", job.name, dtis::io::StreamEndName(r.end)),
                          *machine, r.table, r.verify, r.limiters, r.compute_s),
            plotly));
  }
  if (!a.quiet) {
    std::fprintf(stderr, "stream           %s after %ld setpoints (%ld of them the stop to rest)\n",
                 dtis::io::StreamEndName(r.end), r.rows, r.stop_rows);
    if (g_interrupted) std::fprintf(stderr, "stopped by       %s\n", SignalName(g_signal).c_str());
    if (!r.error.empty()) std::fprintf(stderr, "planner error    %s\n", r.error.c_str());
    std::fprintf(stderr, "segments         %d planned, pace %s, buffer %ld periods, horizon %ld\n",
                 r.segments, o.realtime ? "real time" : "as fast as the output takes",
                 o.buffer_periods, static_cast<long>(o.commit_horizon));
    std::fprintf(stderr,
                 "underruns        %ld, rows held at rest %ld, peak queue %ld, largest hand-over "
                 "%ld\n",
                 stream.Status().underruns.load(), stream.Status().holds.load(), r.peak_queued,
                 r.largest_handover);
    std::fprintf(stderr, "compute          %.3f s planning, %.3f s wall\n", r.compute_s, r.wall_s);
    if (r.rows >= 2) {
      std::fprintf(stderr, "verify           worst ratio %.9f (%s), %s\n", r.verify.worst_ratio,
                   r.verify.worst.c_str(), r.verify.Passed() ? "PASS" : "FAIL");
    }
    if (record) std::fprintf(stderr, "recorded         %s\n", a.record.c_str());
    if (!a.report.empty() && r.rows >= 2)
      std::fprintf(stderr, "report           %s\n", a.report.c_str());
  }
  if (r.rows >= 2 && !r.verify.Passed()) return kExitVerifyFailed;
  return r.end == dtis::io::StreamEnd::kComplete ? 0 : kExitStreamEndedEarly;
}

// --jerk-time-ms: for LinuxCNC INI machines without MAX_JERK (0: not given; the machine's reader
// refuses any other value out of range, NaN included).
dtis::kinematics::MachineLoadOptions JerkTime(double ms) {
  dtis::kinematics::MachineLoadOptions o;
  if (ms != 0.0) o.jerk_time_s = ms * 1e-3;
  return o;
}

constexpr const char* kJerkTimeHelp =
    "for a LinuxCNC INI without MAX_JERK: each axis' jerk = MAX_ACCELERATION / this time (ms)";

struct ServeArgs {
  std::string socket, machine, to = "-", record_dir, pace = "realtime", from, planner;
  long buffer = 200, low_water = 20;
  bool index = false;
  double jerk_time_ms = 0.0;
};

std::string DefaultSocket() {
  const char* runtime = std::getenv("XDG_RUNTIME_DIR");
  return runtime ? fmt::format("{}/dtis.sock", runtime)
                 : fmt::format("/tmp/dtis-{}.sock", getuid());
}

int Serve(const ServeArgs& a) {
  KeepStopSignals();
  dtis::io::ServeOptions o;
  o.stop = &g_interrupted;
  o.socket_path = a.socket.empty() ? DefaultSocket() : a.socket;
  o.machine_file = a.machine;
  o.record_dir = a.record_dir;
  o.stream.buffer_periods = a.buffer;
  o.stream.low_water_periods = a.low_water;
  o.stream.realtime = a.pace == "realtime";
  o.machine_options = JerkTime(a.jerk_time_ms);
  const auto machine = dtis::kinematics::LoadMachineFile(a.machine, o.machine_options);
  if (!a.from.empty()) o.from = ParseAxisPositions(a.from, *machine);
  if (!a.planner.empty()) o.planner = dtis::interp::PlannerFromName(a.planner);
  if (!a.record_dir.empty()) std::filesystem::create_directories(a.record_dir);
  StreamOutput output(a.to, *machine, a.index, a.buffer);
  o.listening = [&o] {
    std::fprintf(stderr, "dtis serve: listening on %s\n", o.socket_path.c_str());
  };
  dtis::io::Serve(o, output.Cnc());
  output.Close();
  if (g_interrupted) {
    std::fprintf(stderr, "dtis serve: stopped by %s, the machine at rest\n",
                 SignalName(g_signal).c_str());
  }
  return 0;
}

// `dtis machine import`: a LinuxCNC INI (or a machine file) written out as a machine file.
int ImportMachine(const std::string& from, const std::string& output, double jerk_time_ms) {
  const auto d = dtis::kinematics::ReadMachineDescription(from, JerkTime(jerk_time_ms));
  dtis::kinematics::BuildMachine(d);  // checks it as a run would
  std::string text = fmt::format("# Imported by dtis {} from {}\n", dtis::kVersion, from);
  text += dtis::kinematics::FormatMachineFile(d);
  if (output.empty() || output == "-") {
    std::fputs(text.c_str(), stdout);
  } else {
    dtis::io::WriteFileAtomically(output, text);
  }
  return 0;
}

// The verifier's report of a setpoint file; its errors (too few rows, times that do not increase,
// other axes) name the file.
dtis::interp::VerifyReport VerifyFile(const std::string& file,
                                      const dtis::interp::SetpointTable& table,
                                      const dtis::Machine& machine) {
  try {
    return dtis::interp::Verify(table, machine);
  } catch (const dtis::Error& e) {
    throw dtis::Error("{}: {}", file, e.what());
  }
}

int Verify(const std::string& setpoints, const std::string& machine_file, double jerk_time_ms) {
  const auto machine = dtis::kinematics::LoadMachineFile(machine_file, JerkTime(jerk_time_ms));
  const auto table = dtis::io::ReadSetpoints(setpoints);
  const dtis::interp::VerifyReport report = VerifyFile(setpoints, table, *machine);
  std::fputs(dtis::interp::FormatReport(report).c_str(), stdout);
  return report.Passed() ? 0 : kExitVerifyFailed;
}

struct ReportArgs {
  std::string setpoints, machine, output, job, limiters;
  double jerk_time_ms = 0.0;
};

int Report(const ReportArgs& a) {
  const std::string plotly = dtis::io::LoadPlotly();
  std::optional<dtis::io::Job> job;
  if (!a.job.empty()) job = dtis::io::LoadJob(a.job);
  if (a.machine.empty() && !job) {
    throw dtis::Error("report {}: give the MACHINE file, or --job for the job's machine",
                      a.setpoints);
  }
  const auto machine = a.machine.empty()
                           ? dtis::io::LoadJobMachine(*job)
                           : dtis::kinematics::LoadMachineFile(a.machine, JerkTime(a.jerk_time_ms));
  const auto table = dtis::io::ReadSetpoints(a.setpoints);
  std::vector<dtis::interp::LimiterId> limiters;
  if (!a.limiters.empty()) {
    limiters = dtis::io::ReadLimiters(a.limiters, dtis::io::AxisNames(*machine));
    if (limiters.size() != table.Rows()) {
      throw dtis::Error("{}: {} rows; the setpoint file {} has {}: not the same run", a.limiters,
                        limiters.size(), a.setpoints, table.Rows());
    }
  }
  const std::string output =
      a.output.empty() ? std::filesystem::path(a.setpoints).replace_extension(".html").string()
                       : a.output;
  const std::string file = std::filesystem::path(a.setpoints).filename().string();
  dtis::io::ReportInput in;
  in.title = job ? fmt::format("{} ({})", job->name, file) : file;
  in.about = {{"setpoints", a.setpoints}};
  if (!job) in.about.push_back({"machine", fmt::format("{} ({})", machine->Name(), a.machine)});
  in.machine = machine.get();
  in.table = &table;
  const dtis::interp::VerifyReport verify = VerifyFile(a.setpoints, table, *machine);
  in.verify = &verify;
  in.limiters = std::move(limiters);
  dtis::io::WriteFileAtomically(output, job ? RenderJobReport(*job, std::move(in), plotly)
                                            : dtis::io::RenderReport(in, plotly));
  std::fprintf(stderr, "wrote            %s\n", output.c_str());
  return 0;
}

int Figures(const std::string& report, const std::string& out_dir, dtis::io::FigureOptions options,
            bool quiet) {
  Progress progress(!quiet);
  std::string line;
  options.waiting = [&](double elapsed_s) {
    line = fmt::format("drawing the figures in Chromium: {:.0f} s (at most {:g} s)", elapsed_s,
                       options.timeout_s);
    progress.Phase(line);
  };
  const auto files = dtis::io::ExportFigures(
      report,
      out_dir.empty() ? std::filesystem::path(report).replace_extension("").string() + "_figures"
                      : out_dir,
      options);
  progress.Clear();
  if (!quiet) {
    for (const auto& f : files) std::fprintf(stderr, "wrote            %s\n", f.c_str());
  }
  return 0;
}

int Faces(const std::string& file) {
  const auto model = dtis::geometry::StepModel::Load(file);
  std::fputs(dtis::geometry::FormatFaceTable(model).c_str(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CatchStopSignals(environ);                // done already, unless the .preinit_array was not run
  unsetenv(dtis::cli::kBlockedByLauncher);  // not for the programs dtis runs
  CLI::App app{
      "dtis: axis setpoints at a fixed period, every axis within its velocity, acceleration and "
      "jerk limits (VPOp, Beudaert et al. 2012)."};
  app.require_subcommand(1);
  app.set_version_flag("--version", fmt::format("dtis {}", dtis::kVersion));
  app.footer(kExitStatusHelp);

  auto* run = app.add_subcommand(
      "run",
      "Plan a job (TOML) and write its setpoints as CSV (t, X, Y, Z then rotary axes in "
      "degrees), atomically. Prints a summary on stderr.");
  RunArgs ra_run;
  run->add_option("JOB", ra_run.job, "job file (see samples/jobs/)")->required();
  run->add_option("-o,--output", ra_run.output,
                  "setpoint file (default: the job's [output] setpoints, else NAME.csv)");
  run->add_option("--limiters", ra_run.limiters,
                  "also write, per setpoint, the arc length, feed and which constraint limited it");
  run->add_option("--report", ra_run.report,
                  "also write a self-contained HTML report (tool path by feed, feed, every axis "
                  "against its limits)");
  run->add_flag("-q,--quiet", ra_run.quiet, "print nothing on success");
  run->add_flag("--keep-failed", ra_run.keep_failed,
                "write the outputs even when the verifier fails the setpoints (exit status 3 "
                "all the same); without it such a run writes nothing");
  run->add_option("--horizon", ra_run.horizon,
                  "commit horizon, periods (overrides the job's): plans what `dtis stream "
                  "--horizon` with the same value sends")
      ->check(CLI::Range(8L, 1L << 30));
  run->add_option("--planner", ra_run.planner, kPlannerHelp)
      ->check(CLI::IsMember({"vpop", "lookahead", "least-time"}));
  run->add_option("-j,--threads", ra_run.threads,
                  "threads for a surface job's passes (0: all cores); the output is the same")
      ->check(kNonNegative);
  run->add_option("--jerk-time-ms", ra_run.jerk_time_ms, kJerkTimeHelp)->check(kPositive);
  run->add_option("--from", ra_run.from,
                  "G-code jobs: where the machine is, X,Y,Z[,A,C] (mm, deg): the program starts "
                  "there (default: the job's [path] from, else the origin)");

  auto* compare = app.add_subcommand(
      "compare",
      "For a surface job, plan the same passes from G1 and B-spline exports at the job's [compare] "
      "tolerances and directly on the surface, and print one table: blocks, planned time, "
      "deviation from the exact path, verification and the limiting axes.");
  CompareArgs ca;
  compare->add_option("JOB", ca.job, "surface job file (see samples/jobs/)")->required();
  compare->add_option("--csv", ca.csv, "also write the table as CSV");
  compare->add_option("--markdown", ca.markdown, "also write the table as Markdown");
  compare->add_option("--exports", ca.exports,
                      "write the exports there: G1 programs (.ngc), B-spline curve files (.toml), "
                      "Siemens BSPLINE programs (.mpf), LinuxCNC G5.2 programs for XY passes");
  compare->add_option("--report", ca.report,
                      "also write a self-contained HTML report: the table, every variant's feed "
                      "against time, and the exact-surface run in full");
  compare
      ->add_option("--planner", ca.planner,
                   "both (every variant planned by each planner, the job's first), vpop, "
                   "lookahead or least-time")
      ->check(CLI::IsMember({"both", "vpop", "lookahead", "least-time"}))
      ->capture_default_str();
  compare->add_flag("-q,--quiet", ca.quiet, "no progress line");
  compare->add_option("-j,--threads", ca.threads, "threads (0: all cores)")->check(kNonNegative);
  compare->add_option("--jerk-time-ms", ca.jerk_time_ms, kJerkTimeHelp)->check(kPositive);

  auto* faces = app.add_subcommand(
      "faces",
      "List the faces of a STEP part file: index, surface type, degree, poles, rational, trimmed, "
      "UV bounds and size (mm). Surface jobs select a face by its index.");
  std::string step_file;
  faces->add_option("FILE", step_file, "STEP file (AP203/AP214/AP242)")->required();

  auto* verify = app.add_subcommand(
      "verify",
      "Check any setpoint file against a machine: per axis the largest |v|, |a|, |j| (backward "
      "differences) as a ratio to its limit, the motion time, and rest at both ends. Exit 0 when "
      "every ratio is <= 1 and the sequence starts and ends at rest, 3 otherwise.");
  std::string setpoints, machine;
  double verify_jerk_time_ms = 0.0;
  verify->add_option("FILE", setpoints, "setpoint CSV")->required();
  verify->add_option("MACHINE", machine, "machine file (see samples/machines/) or LinuxCNC INI")
      ->required();
  verify->add_option("--jerk-time-ms", verify_jerk_time_ms, kJerkTimeHelp)->check(kPositive);

  auto* machine_cmd =
      app.add_subcommand("machine", "Machines: import a LinuxCNC INI file as a dtis machine file.");
  machine_cmd->require_subcommand(1);
  auto* import = machine_cmd->add_subcommand(
      "import",
      "Read a LinuxCNC INI file (KINEMATICS, COORDINATES, units, [JOINT_n]/[AXIS_L] limits, the "
      "kinematics' pivot pins from its HAL files) and write it as a machine file in mm, s, deg.");
  std::string import_from, import_output;
  double import_jerk_time_ms = 0.0;
  import->add_option("INI", import_from, "LinuxCNC INI file (or a machine file)")->required();
  import->add_option("-o,--output", import_output, "machine file to write (default: stdout)");
  import->add_option("--jerk-time-ms", import_jerk_time_ms, kJerkTimeHelp)->check(kPositive);

  auto* report = app.add_subcommand(
      "report",
      "Write a self-contained HTML report of any setpoint file (a run, a stream recording, a HAL "
      "capture): the tool tip path coloured by feed, feed against time, every axis' position, "
      "velocity, acceleration and jerk against its limits, and the verifier's summary; with --job "
      "the programmed feed and the face, with --limiters the constraint that decided each "
      "period.");
  ReportArgs ra;
  report->add_option("FILE", ra.setpoints, "setpoint CSV")->required();
  report->add_option("MACHINE", ra.machine, "machine file (default: the --job's)");
  report->add_option("--jerk-time-ms", ra.jerk_time_ms, kJerkTimeHelp)->check(kPositive);
  report->add_option("-o,--output", ra.output, "HTML file (default: FILE with .html)");
  report->add_option("--job", ra.job,
                     "the job the setpoints came from: its machine, programmed feed and, for a "
                     "surface job, the face drawn under the path");
  report->add_option("--limiters", ra.limiters,
                     "the run's limiter report (dtis run --limiters): the constraint that decided "
                     "each period, as a band under the feed");

  auto* figures = app.add_subcommand(
      "figures",
      "Draw the figures of an HTML report (dtis run/report/compare/stream --report) as PNG and SVG "
      "files at print size for papers, with headless Chromium: the report's plots, laid out for a "
      "column (or --width-mm) by the same plotly.js.");
  std::string figures_report, figures_dir;
  dtis::io::FigureOptions fo;
  bool figures_quiet = false;
  figures->add_option("REPORT", figures_report, "HTML report")->required();
  figures->add_option("-o,--output", figures_dir,
                      "folder for NAME.FORMAT files (default: REPORT without .html, + _figures)");
  figures->add_option("--format", fo.formats, "comma-separated: png, svg, jpeg, webp")
      ->delimiter(',')
      ->capture_default_str();
  figures
      ->add_option("--width-mm", fo.width_mm,
                   "print width of every figure, mm (88: a column of a two-column paper, 180: a "
                   "page); heights follow each plot, text is 7 to 8 pt")
      ->capture_default_str()
      ->check(CLI::Range(40.0, 500.0));
  figures->add_option("--dpi", fo.dpi, "resolution of the PNGs, dots per inch (written in them)")
      ->capture_default_str()
      ->check(CLI::Range(72, 1200));
  figures
      ->add_option("--pass", fo.pass,
                   "a surface job's feed figure shows this pass alone (1: the first; the report's "
                   "selector does the same)")
      ->check(CLI::PositiveNumber);
  figures->add_flag("-q,--quiet", figures_quiet, "print nothing on success");

  auto* stream = app.add_subcommand(
      "stream",
      "Plan a job and hand each setpoint over as soon as it is final, as lines for LinuxCNC's "
      "halstreamer (one per period: the axes in mm and degrees). Aborted (SIGINT, SIGTERM or any "
      "other signal that would end dtis; SIGKILL cannot be caught), starved or failed streams end "
      "with a stop to rest within every axis limit. Exit 0: complete; 5: ended early at rest; 3: "
      "the stream failed the verifier; 1: bad input, or the output's reader died (what was sent "
      "is recorded).");
  StreamArgs sa;
  stream->add_option("JOB", sa.job, "job file (see samples/jobs/)")->required();
  stream->add_option("--to", sa.to, kStreamToHelp)->capture_default_str();
  stream->add_option("--buffer", sa.buffer, "setpoints kept ahead of the machine, periods")
      ->capture_default_str()
      ->check(kPositive);
  stream
      ->add_option("--horizon", sa.horizon,
                   "steps the planner keeps open to back-off before handing them over (default: "
                   "the job's commit_horizon, else 256); `dtis run --horizon` with the same value "
                   "plans the very same setpoints")
      ->check(CLI::Range(8L, 1L << 30));
  stream
      ->add_option("--low-water", sa.low_water,
                   "in real time: when the planner has nothing new and the machine holds fewer "
                   "periods than this, play the stop (an underrun)")
      ->capture_default_str()
      ->check(kNonNegative);
  stream
      ->add_option("--pace", sa.pace,
                   "realtime: write at the machine's pace; none: as fast as the output takes "
                   "rows; auto: realtime unless the output is a regular file")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "realtime", "none"}));
  stream->add_flag("--index", sa.index,
                   "add a last column with the period number + 1 (a u32 streamer pin)");
  stream->add_option("--record", sa.record,
                     "also write what was streamed as a setpoint CSV (for dtis verify)");
  stream->add_option("--report", sa.report,
                     "also write a self-contained HTML report of what was streamed (stop "
                     "included)");
  stream->add_option("--from", sa.from,
                     "where the machine is, X,Y,Z[,A,C] (mm, deg): a G-code program starts there; "
                     "to any other job a link leads from there to its start");
  stream
      ->add_option("--slow-planner-us", sa.slow_planner_us,
                   "testing: the planner sleeps this long per setpoint (to make it fall behind)")
      ->check(kNonNegative);
  stream->add_option("--planner", sa.planner, kPlannerHelp)
      ->check(CLI::IsMember({"vpop", "lookahead"}));
  stream->add_option("--jerk-time-ms", sa.jerk_time_ms, kJerkTimeHelp)->check(kPositive);
  stream->add_flag("-q,--quiet", sa.quiet, "print nothing on success");

  auto* serve = app.add_subcommand(
      "serve",
      "Stay up and stream jobs submitted over a local socket to one CNC, one after the other, each "
      "linked from where the previous one left the machine (see `dtis send`). SIGTERM, SIGINT or "
      "any other signal that would end it (not SIGKILL) is a shutdown: the job's stop to rest, its "
      "recording written, the socket removed.");
  ServeArgs va;
  serve->add_option("--socket", va.socket, "Unix socket (default $XDG_RUNTIME_DIR/dtis.sock)");
  serve->add_option("--machine", va.machine, "the CNC's machine file; jobs must use it")
      ->required();
  serve->add_option("--jerk-time-ms", va.jerk_time_ms, kJerkTimeHelp)->check(kPositive);
  serve->add_option("--to", va.to, kStreamToHelp)->capture_default_str();
  serve->add_option("--buffer", va.buffer, "setpoints kept ahead of the machine, periods")
      ->capture_default_str()
      ->check(kPositive);
  serve->add_option("--low-water", va.low_water, "underrun threshold, periods")
      ->capture_default_str()
      ->check(kNonNegative);
  serve->add_option("--pace", va.pace, "realtime or none")
      ->capture_default_str()
      ->check(CLI::IsMember({"realtime", "none"}));
  serve->add_flag("--index", va.index, "add the period number + 1 as a last column");
  serve->add_option("--record-dir", va.record_dir, "write job-<id>.csv there: what was streamed");
  serve->add_option("--from", va.from, "where the machine is before the first job, X,Y,Z[,A,C]");
  serve
      ->add_option("--planner", va.planner,
                   "plan every job with vpop or lookahead, whatever its [interpolator] planner")
      ->check(CLI::IsMember({"vpop", "lookahead"}));

  auto* send = app.add_subcommand(
      "send",
      "Send one request to `dtis serve` and print the reply: {\"cmd\":\"submit\",\"job\":PATH}, "
      "status, pause (at the end of the current segment), resume, abort (stop to rest), shutdown.");
  std::string send_socket, request;
  send->add_option("--socket", send_socket, "Unix socket (default $XDG_RUNTIME_DIR/dtis.sock)");
  send->add_option("REQUEST", request, "one JSON object")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version print and succeed; every other parse error is a usage error.
    const int rc = app.exit(e);
    return rc == 0 ? 0 : kExitUsage;
  }
  if (!*stream && !*serve) ReleaseStopSignals();
  try {
    if (*report) return Report(ra);
    if (*figures) return Figures(figures_report, figures_dir, fo, figures_quiet);
    if (*run) return Run(ra_run);
    if (*faces) return Faces(step_file);
    if (*compare) return Compare(ca);
    if (*verify) return Verify(setpoints, machine, verify_jerk_time_ms);
    if (*import) return ImportMachine(import_from, import_output, import_jerk_time_ms);
    if (*stream) return Stream(sa);
    if (*serve) return Serve(va);
    if (*send) {
      std::signal(SIGPIPE, SIG_IGN);  // a daemon gone mid-request is an error message, not a death
      const std::string reply =
          dtis::io::SendRequest(send_socket.empty() ? DefaultSocket() : send_socket, request);
      std::puts(reply.c_str());
      return reply.find("\"ok\":true") != std::string::npos ? 0 : kExitBadInput;
    }
  } catch (const dtis::Error& e) {
    std::fprintf(stderr, "dtis: error: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dtis: internal error: %s (please report it with the job)\n", e.what());
    return kExitInternal;
  } catch (...) {
    std::fputs("dtis: internal error: an unknown exception (please report it with the job)\n",
               stderr);
    return kExitInternal;
  }
  return 0;
}
