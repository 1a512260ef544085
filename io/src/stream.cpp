#include "dtis/io/stream.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <numbers>
#include <thread>

#include "dtis/core/error.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/g1_path.hpp"
#include "dtis/interp/program.hpp"
#include "dtis/io/gcode_program.hpp"

namespace dtis::io {
namespace {

using Clock = std::chrono::steady_clock;

// ---- segment sources

// The first pose of a path as the planner computes it (default branch), where a link must lead.
Pose StartPose(const PathSource& path, const Machine& machine) {
  const PathSample s0 = path.At(path.Start(), 0.0);
  AxisVector q;
  const InverseResult r = machine.Inverse(s0.pose, nullptr, &q);
  if (r.status != InverseStatus::kOk) {
    throw Error("the start of {}: {}", path.Describe(s0.state), DescribeInverseFailure(machine, r));
  }
  return machine.Forward(q);
}

// Links from where the machine is to where `next` starts, when they differ, their corners smoothed
// with `corners` (whose feed is the link feed).
class Linker {
 public:
  Linker(const Machine& machine, interp::VpopOptions options, double clearance,
         geometry::CornerOptions corners)
      : machine_(machine),
        options_(std::move(options)),
        clearance_(clearance),
        corners_(std::move(corners)) {}

  // Queues the link moves from `at` to the start of `next` (none when already there), traversing
  // at the height `heights` gives (none: above both ends by the clearance).
  void LinkTo(const std::optional<AxisVector>& at, const PathSource& next,
              const geometry::LinkHeights* heights, const std::string& name,
              bool straight = false) {
    if (!at) return;
    const Pose from = machine_.Forward(*at);
    const Pose to = StartPose(next, machine_);
    if ((from.tip - to.tip).norm() < 1e-9 && (from.axis - to.axis).norm() < 1e-12) return;
    const double z =
        heights ? heights->TraverseZ(from, to) : std::max(from.tip.z(), to.tip.z()) + clearance_;
    for (auto& m : geometry::LinkMoves(from, to, z, clearance_, machine_, corners_, straight)) {
      pending_.push_back({std::shared_ptr<const PathSource>(std::move(m)), options_, name, -1});
    }
  }
  std::optional<StreamSegment> Pop() {
    if (pending_.empty()) return std::nullopt;
    StreamSegment s = std::move(pending_.front());
    pending_.pop_front();
    return s;
  }

 private:
  const Machine& machine_;
  interp::VpopOptions options_;
  double clearance_;
  geometry::CornerOptions corners_;
  std::deque<StreamSegment> pending_;
};

// Links between jobs: corners smoothed as by default, at the link feed.
geometry::CornerOptions LinkCorners(const interp::VpopOptions& link) {
  geometry::CornerOptions corners;
  corners.feed_mm_s = link.feed_mm_s;
  return corners;
}

// Paths one after the other, as `next` builds them (a line, a curve, a G-code program's contours
// and rapids), after a link from `from` to the first.
class ListSegments final : public SegmentSource {
 public:
  using Producer = std::function<std::optional<StreamSegment>()>;
  ListSegments(Producer next, const Machine& machine, std::optional<AxisVector> from,
               const interp::VpopOptions& link, double clearance)
      : next_(std::move(next)),
        linker_(machine, link, clearance, LinkCorners(link)),
        from_(std::move(from)) {}
  void StartFrom(const std::optional<AxisVector>& from) override { from_ = from; }
  std::optional<StreamSegment> Next(const std::optional<AxisVector>& at) override {
    if (auto link = linker_.Pop()) return link;
    if (!started_) {
      started_ = true;
      first_ = next_();
      if (first_ && from_) {
        linker_.LinkTo(from_, *first_->path, nullptr, "link to the start");
        if (auto link = linker_.Pop()) return link;
      }
    }
    (void)at;
    if (first_) {
      std::optional<StreamSegment> first;
      first.swap(first_);
      return first;
    }
    return next_();
  }

 private:
  Producer next_;
  Linker linker_;
  std::optional<AxisVector> from_;
  bool started_ = false;
  std::optional<StreamSegment> first_;
};

// A G-code program's segments, built as the stream reaches them: the machine holds one chain of
// moves at a time, not the program, and of a chain longer than window_blocks only what lies
// around the planner. The program is read and its segments built once before, so that a bad
// block or corner, or a program that runs for more than a job may take, is reported before
// anything moves. `cancel` stops those reads.
class GcodeProducer {
 public:
  GcodeProducer(const Job& job, const Machine& machine, Cancel* cancel)
      : file_(job.path.gcode_file) {
    const GcodeInterpreter which = job.path.gcode.interpreter;
    const std::shared_ptr<const ToolTable>& tools = job.path.gcode.tool_table;
    GcodeStart start;
    try {
      start = GcodeStartOf(job.path.gcode, machine);
    } catch (const Error& e) {
      throw Error("{}: [path] {}", job.file, e.what());
    }
    // A read that fails because it was cancelled says so.
    const auto checked = [cancel](auto&& read) {
      try {
        read();
      } catch (const Error&) {
        if (cancel != nullptr) cancel->ThrowIfRequested();
        throw;
      }
      if (cancel != nullptr) cancel->ThrowIfRequested();
    };
    // In the order `dtis run` finds them: bad blocks, rotary words the machine lacks, corners.
    std::array<bool, 3> uses_rotary{};
    checked([&] {
      GcodeReader blocks(file_, which, tools, cancel, start);
      // The program's least time, as `dtis run` counts it: one that moves for more than a job
      // may (24 h), an endless loop among them, is refused as soon as it has gone past that.
      ProgramLeastTime least(file_, job.vpop.max_motion_s);
      const double rapid_feed = RapidFeed(job.path.gcode, machine);
      Eigen::Vector3d at = start.tip;
      while (const auto m = blocks.Next()) {
        least.Add(*m, at, MoveFeed(*m, job.path.gcode, rapid_feed), m->dwell_s);
        at = m->to;
        if (cancel != nullptr) cancel->ThrowIfRequested();
      }
      uses_rotary = blocks.UsesRotary();
    });
    const auto build = [&](GcodeReader& reader, Cancel* stop) {
      return std::make_unique<GcodeSegments>(
          [&reader, stop] {
            if (stop != nullptr) stop->ThrowIfRequested();
            return reader.Next();
          },
          file_, uses_rotary, machine, job.vpop, job.path.gcode);
    };
    // Which long chains turn the tool: they are smoothed as 5-axis chains from their first move.
    std::vector<bool> five_axis;
    checked([&] {
      GcodeReader reader(file_, which, tools, cancel, start);
      const auto scan = build(reader, cancel);
      scan->ScanOnly();
      while (const auto s = scan->Next()) {
        if (s->windowed) five_axis.push_back(s->five_axis);
      }
    });
    checked([&] {
      GcodeReader reader(file_, which, tools, cancel, start);
      const auto all = build(reader, cancel);
      all->SetWindowedFiveAxis(five_axis);
      while (const auto s = all->Next()) {
        if (s->windowed) static_cast<const geometry::G1Path&>(*s->path).Check();
      }
    });
    // What streams: read when the stream gets there, after `cancel` may be gone.
    reader_ = std::make_unique<GcodeReader>(file_, which, tools, nullptr, start);
    segments_ = build(*reader_, nullptr);
    segments_->SetWindowedFiveAxis(std::move(five_axis));
  }
  std::optional<StreamSegment> operator()() {
    std::optional<GcodeSegment> s = segments_->Next();
    if (!s) return std::nullopt;
    return StreamSegment{std::shared_ptr<const PathSource>(std::move(s->path)), s->options,
                         std::move(s->name), -1, s->dwell_before_s};
  }

 private:
  std::string file_;
  std::unique_ptr<GcodeReader> reader_;
  std::unique_ptr<GcodeSegments> segments_;
};

// A surface job: pass 1, the links from where it really ended to pass 2, pass 2, ...
class SurfaceSegments final : public SegmentSource {
 public:
  SurfaceSegments(const Job& job, const Machine& machine, std::optional<AxisVector> from,
                  Cancel* cancel)
      : setup_(SetUpSurface(job)),
        linker_(machine, setup_.link_options, setup_.clearance_mm, setup_.link_corners),
        from_(std::move(from)) {
    double length_mm = 0.0;
    for (const auto& pass : setup_.passes.passes) length_mm += pass->Length().value_or(0.0);
    CheckMotionBound(job, length_mm);
    if (cancel != nullptr) cancel->ThrowIfRequested();
    CheckPassesInTravel(setup_, machine, job.file);
  }
  void StartFrom(const std::optional<AxisVector>& from) override { from_ = from; }
  std::string Notes() const override { return setup_.passes.UnreachableText(kSummaryUnreachable); }
  std::optional<StreamSegment> Next(const std::optional<AxisVector>& at) override {
    if (auto link = linker_.Pop()) return link;
    const auto& passes = setup_.passes.passes;
    if (next_ >= passes.size()) return std::nullopt;
    const std::size_t k = next_;
    const std::optional<AxisVector>& here = k == 0 ? from_ : at;
    if (!linked_to_next_) {
      linked_to_next_ = true;
      const std::string name = k == 0 ? std::string("link to pass 1")
                                      : fmt::format("link from pass {} to pass {}", k, k + 1);
      linker_.LinkTo(here, *passes[k], setup_.link_heights.get(), name,
                     k > 0 && passes[k]->RidesOverFromPrevious());
      if (auto link = linker_.Pop()) return link;
    }
    linked_to_next_ = false;
    ++next_;
    // The pass list owns the pass; the setup outlives every segment handed out.
    return StreamSegment{
        std::shared_ptr<const PathSource>(std::shared_ptr<void>(), passes[k].get()),
        setup_.pass_options, fmt::format("pass {}", k + 1), static_cast<int>(k)};
  }

 private:
  SurfaceSetup setup_;
  Linker linker_;
  std::optional<AxisVector> from_;
  std::size_t next_ = 0;
  bool linked_to_next_ = false;
};

}  // namespace

std::unique_ptr<SegmentSource> JobSegments(const Job& job, const Machine& machine,
                                           const std::optional<AxisVector>& from,
                                           double clearance_mm, Cancel* cancel) {
  if (cancel != nullptr) cancel->ThrowIfRequested();
  if (job.interpolator != InterpolatorKind::kVpop) {
    throw Error("{}: only VPOp jobs can be streamed (the Taylor interpolators are baselines)",
                job.file);
  }
  if (job.surface) return std::make_unique<SurfaceSegments>(job, machine, from, cancel);
  ListSegments::Producer next;
  if (job.path.kind == PathSpec::Kind::kGcode) {
    // A program starts where the machine is, as LinuxCNC runs it: `from`, else the job's start.
    Job started = job;
    if (from) started.path.gcode.from = GcodeFrom(*from, machine);
    next = [producer = std::make_shared<GcodeProducer>(started, machine, cancel)] {
      return (*producer)();
    };
  } else {
    std::shared_ptr<const PathSource> path = BuildPath(job);
    CheckMotionBound(job, path->Length().value_or(0.0));
    next = [segment = std::optional<StreamSegment>(
                StreamSegment{std::move(path), job.vpop, "path"})]() mutable {
      std::optional<StreamSegment> s;
      s.swap(segment);
      return s;
    };
  }
  // A G-code job's own feed is a placeholder (its F words rule): its links move at its rapids'.
  interp::VpopOptions link = job.vpop;
  if (job.path.kind == PathSpec::Kind::kGcode) link.feed_mm_s = RapidFeed(job.path.gcode, machine);
  return std::make_unique<ListSegments>(std::move(next), machine, from, link, clearance_mm);
}

// ---- outputs

HalstreamerOutput::HalstreamerOutput(std::FILE* file, int axes, bool index_column)
    : file_(file), axes_(axes), index_column_(index_column) {}

void HalstreamerOutput::Write(const StreamRow& row) {
  fmt::memory_buffer line;
  for (int i = 0; i < axes_; ++i)
    fmt::format_to(std::back_inserter(line), "{}{}", i ? " " : "", row.q[i]);
  if (index_column_) fmt::format_to(std::back_inserter(line), " {}", row.row + 1);
  line.push_back('\n');
  last_.assign(line.data(), line.size());
  if (std::fwrite(line.data(), 1, line.size(), file_) != line.size()) {
    throw Error("cannot write the stream: {}", std::strerror(errno));
  }
}

void HalstreamerOutput::Flush() {
  if (std::fflush(file_) != 0) throw Error("cannot write the stream: {}", std::strerror(errno));
}

void HalstreamerOutput::Close() {
  if (!last_.empty()) std::fwrite(last_.data(), 1, last_.size(), file_);
  Flush();
}

// ---- the stream

std::size_t StreamHorizon(const Job& job) {
  return job.vpop.commit_horizon != interp::VpopOptions{}.commit_horizon ? job.vpop.commit_horizon
                                                                         : kStreamCommitHorizon;
}

const char* StreamEndName(StreamEnd end) {
  switch (end) {
    case StreamEnd::kComplete:
      return "complete";
    case StreamEnd::kAborted:
      return "aborted";
    case StreamEnd::kStarved:
      return "underrun";
    case StreamEnd::kFailed:
      return "failed";
  }
  return "?";
}

namespace {

// A planned row on its way to the machine. The last row of each hand-over carries the stop that
// may follow it.
struct Entry {
  interp::Setpoint sp;  // global index, rotary axes unwrapped onto the previous segment
  int segment = 0;
  int pass = -1;
  std::shared_ptr<const std::vector<interp::Setpoint>> stop;
};

}  // namespace

struct Stream::Shared {
  std::mutex mutex;
  std::condition_variable ready;  // rows or the end arrived (for the feeder)
  std::condition_variable space;  // rows left the queue, or abort (for the planner)
  std::deque<Entry> queue;
  bool planner_done = false;
  std::string error;
  double compute_s = 0.0;
  long largest_handover = 0;
};

namespace {

// Receives one segment's setpoints from the planner: joins them onto the rows streamed before
// (the first row repeats where the previous segment ended; continuous rotary axes are shifted by
// whole turns, as Stitch does) and hands them to the queue, a hand-over at a time.
class SegmentSink final : public interp::SetpointSink {
 public:
  using Push = std::function<bool(std::vector<Entry>&&, std::vector<interp::Setpoint>&&)>;
  SegmentSink(const Machine& machine, const std::optional<AxisVector>& previous, long base,
              long hold, int segment, int pass, long slow_us, const std::atomic<bool>& abort,
              Push push)
      : machine_(machine),
        previous_(previous),
        base_(base),
        hold_(hold),
        segment_(segment),
        pass_(pass),
        slow_us_(slow_us),
        abort_(abort),
        push_(std::move(push)),
        shift_(AxisVector::Zero(machine.AxisCount())) {}

  void Accept(const interp::Setpoint& sp) override {
    if (sp.index != 0) {
      Queue(sp);
      return;
    }
    // The first row: where the previous segment ended (not streamed again), or where the job
    // starts. A dwell holds it there, as interp::Stitch does.
    AxisVector here = sp.q;
    if (previous_) {
      misaligned_ = !Align(sp.q);
      if (misaligned_) return;
      here = *previous_;
    } else {
      Queue(sp);
    }
    interp::Setpoint held = sp;
    held.q = here;
    for (long r = 0; r < hold_; ++r) {
      held.index = base_ + 1 + r;
      Add(held);
    }
    base_ += hold_;
  }
  bool WantsStops() const override { return true; }
  void AcceptStop(const std::vector<interp::Setpoint>& stop) override {
    // Nothing new handed over: the stop offered before still holds.
    if (misaligned_ || abort_ || pending_.empty()) return;
    std::vector<interp::Setpoint> rows = stop;
    for (auto& r : rows) {
      r.index += base_;
      r.q += shift_;
    }
    if (!push_(std::move(pending_), std::move(rows))) stopped_ = true;
    pending_.clear();
  }
  bool Done() const override { return misaligned_ || stopped_ || abort_; }

  bool Misaligned() const { return misaligned_; }
  const std::optional<AxisVector>& LastQ() const { return last_q_; }
  long LastIndex() const { return last_index_; }

 private:
  // A planned row, numbered over the job and shifted onto the previous segment's turns.
  void Queue(const interp::Setpoint& sp) {
    interp::Setpoint row = sp;
    row.index = base_ + sp.index;
    row.q += shift_;
    Add(row);
    if (slow_us_ > 0 && !abort_) std::this_thread::sleep_for(std::chrono::microseconds(slow_us_));
  }
  // A row as it is handed over.
  void Add(const interp::Setpoint& row) {
    last_q_ = row.q;
    last_index_ = row.index;
    pending_.push_back(Entry{row, segment_, pass_, nullptr});
  }
  // Whether the segment starts where the previous one ended, give or take whole turns of
  // continuous axes and a few ulps (a hair away, it is planned again from there, as
  // interp::Stitch does).
  bool Align(const AxisVector& first) {
    const std::optional<AxisVector> shift = interp::TurnShift(machine_, *previous_, first);
    if (shift) shift_ = *shift;
    return shift.has_value() && interp::StartsWhereHeld(*previous_, first + shift_);
  }

  const Machine& machine_;
  std::optional<AxisVector> previous_;
  long base_, hold_;
  int segment_, pass_;
  long slow_us_;
  const std::atomic<bool>& abort_;
  Push push_;
  AxisVector shift_;
  std::vector<Entry> pending_;
  std::optional<AxisVector> last_q_;
  long last_index_ = 0;
  bool misaligned_ = false, stopped_ = false;
};

}  // namespace

Stream::Stream(const Machine& machine, const StreamOptions& options)
    : machine_(machine), o_(options), shared_(std::make_unique<Shared>()) {
  if (!(o_.period_s > 0.0)) throw Error("stream: period must be > 0 s");
  if (o_.buffer_periods < 1) throw Error("stream: buffer must be at least 1 period");
  if (o_.commit_horizon < 8) throw Error("stream: commit horizon must be at least 8 periods");
  if (o_.low_water_periods < 0 || o_.low_water_periods >= o_.buffer_periods) {
    throw Error("stream: the low-water mark ({}) must be below the buffer ({} periods)",
                o_.low_water_periods, o_.buffer_periods);
  }
}

Stream::~Stream() = default;

void Stream::Abort() {
  abort_ = true;
  std::lock_guard lock(shared_->mutex);
  shared_->ready.notify_all();
  shared_->space.notify_all();
}

void Stream::Pause() { paused_ = true; }

void Stream::Resume() {
  paused_ = false;
  std::lock_guard lock(shared_->mutex);
  shared_->space.notify_all();
}

StreamResult Stream::Run(SegmentSource& segments, CncOutput& out, SetpointWriter* record) {
  Shared& sh = *shared_;
  const Clock::time_point started = Clock::now();
  // Hands a batch to the queue; waits while the queue is full. False once aborted.
  const long capacity = std::max<long>(o_.buffer_periods, 64);
  double waited = 0.0;  // planner thread: time spent waiting for room in the queue
  auto push = [&](std::vector<Entry>&& rows, std::vector<interp::Setpoint>&& stop) {
    std::unique_lock lock(sh.mutex);
    const auto wait_start = Clock::now();
    sh.space.wait(lock, [&] { return abort_ || static_cast<long>(sh.queue.size()) < capacity; });
    waited += std::chrono::duration<double>(Clock::now() - wait_start).count();
    if (abort_) return false;
    sh.largest_handover = std::max(sh.largest_handover, static_cast<long>(rows.size()));
    rows.back().stop = std::make_shared<const std::vector<interp::Setpoint>>(std::move(stop));
    for (auto& e : rows) sh.queue.push_back(std::move(e));
    status_.queued = static_cast<long>(sh.queue.size());
    sh.ready.notify_all();
    return true;
  };

  // ---- the planner thread
  std::thread planner([&] {
    double busy = 0.0;
    std::string error;
    int k = 0;
    try {
      std::optional<AxisVector> at;
      long base = 0;
      for (;; ++k) {
        {
          std::unique_lock lock(sh.mutex);
          sh.space.wait(lock, [&] { return abort_ || !paused_; });
        }
        if (abort_) break;
        const auto t0 = Clock::now();
        std::optional<StreamSegment> seg = segments.Next(at);
        if (!seg) break;
        status_.segments_planned = k + 1;
        interp::VpopOptions options = seg->options;
        options.commit_horizon = o_.commit_horizon;
        std::optional<SegmentSink> sink;
        for (int attempt = 0; attempt < 2; ++attempt) {
          if (attempt == 1) options.previous_q = at;
          sink.emplace(machine_, at, base, interp::DwellRows(seg->dwell_before_s, options.period_s),
                       k, seg->pass, o_.slow_planner_us, abort_, push);
          try {
            interp::PlanVpop(*seg->path, machine_, options, *sink);
          } catch (const Error& e) {
            throw Error("{}: {}", seg->name, e.what());
          }
          if (!sink->Misaligned()) break;
        }
        if (sink->Misaligned()) {
          throw Error(
              "{}: starts at other axis positions than where the previous segment ended: "
              "the path is not continuous there",
              seg->name);
        }
        busy += std::chrono::duration<double>(Clock::now() - t0).count();
        if (abort_) break;
        if (sink->LastQ()) {
          at = sink->LastQ();
          base = sink->LastIndex();
        }
      }
    } catch (const Error& e) {
      error = e.what();
    } catch (const std::exception& e) {
      error = fmt::format("internal error: {}", e.what());
    } catch (...) {
      error = "internal error: an unknown exception";
    }
    std::lock_guard lock(sh.mutex);
    sh.planner_done = true;
    sh.error = error;
    sh.compute_s = busy - waited;
    sh.ready.notify_all();
  });

  // ---- the feeder (this thread)
  StreamResult result;
  if (o_.keep_rows) {
    result.table.axes = AxisNames(machine_);
    result.table.columns.resize(result.table.axes.size());
  }
  const FileUnits file_units(machine_);
  interp::StreamVerifier verifier(machine_, o_.period_s);
  double units[kMaxAxes];
  std::optional<Clock::time_point> t0;  // when the machine got the first row
  long written = 0;
  Entry last;  // the last row written
  bool any = false;
  bool holding = false;  // the last row written was held at rest
  long peak = 0;

  const auto ahead = [&]() -> long {
    if (auto q = out.Queued()) return *q;
    if (!t0) return 0;
    const double played = std::chrono::duration<double>(Clock::now() - *t0).count() / o_.period_s;
    return std::max<long>(0, written - static_cast<long>(std::floor(played)));
  };
  const auto write = [&](const Entry& e) {
    if (o_.realtime) {
      // Stay at most buffer_periods ahead of the machine.
      for (;;) {
        const long a = ahead();
        if (a < o_.buffer_periods) break;
        if (out.Queued()) {
          std::this_thread::sleep_for(std::chrono::duration<double>(o_.period_s / 2));
        } else {
          std::this_thread::sleep_until(
              *t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                        static_cast<double>(written - o_.buffer_periods + 1) * o_.period_s)));
        }
      }
    }
    file_units.FromPlanner(e.sp.q, units);
    const double t = static_cast<double>(written) * o_.period_s;
    out.Write({written, e.sp.index, e.sp.s, units, e.segment});
    if (record) record->Row(t, units);
    if (o_.keep_rows) {
      result.table.Append(t, units);
      result.limiters.push_back(e.sp.limiter);
    }
    verifier.Add(t, units);
    if (!t0) t0 = Clock::now();
    ++written;
    status_.rows = written;
    status_.segment = e.segment;
    status_.pass = e.pass;
    status_.s_mm = e.sp.s;
    status_.ahead = ahead();
    if (o_.realtime) out.Flush();
  };
  // The stop offered with the last row written: the rows after it, then the end.
  const auto play_stop = [&](StreamEnd why) {
    result.end = why;
    if (any && last.stop) {
      for (const auto& sp : *last.stop) {
        Entry e{sp, last.segment, last.pass, nullptr};
        write(e);
        ++result.stop_rows;
      }
    }
  };
  const auto is_hold = [&](const Entry& e) {
    if (!e.stop) return false;
    return std::all_of(e.stop->begin(), e.stop->end(),
                       [&](const interp::Setpoint& sp) { return sp.q == e.sp.q; });
  };

  try {
    std::unique_lock lock(sh.mutex);
    for (;;) {
      const bool batch_end = !any || last.stop != nullptr;
      if (abort_ && batch_end) {
        lock.unlock();
        play_stop(StreamEnd::kAborted);
        break;
      }
      // Before the first row, and after holding at rest for a planner that fell behind, start
      // only with a full buffer's worth planned (or the whole rest of the job).
      const bool filling = (!any || holding) && !sh.planner_done && !abort_ &&
                           static_cast<long>(sh.queue.size()) < o_.buffer_periods;
      if (!sh.queue.empty() && !filling) {
        holding = false;
        Entry e = std::move(sh.queue.front());
        sh.queue.pop_front();
        peak = std::max(peak, static_cast<long>(sh.queue.size()) + 1);
        status_.queued = static_cast<long>(sh.queue.size());
        sh.space.notify_all();
        lock.unlock();
        write(e);
        last = std::move(e);
        any = true;
        lock.lock();
        continue;
      }
      if (sh.planner_done) {
        lock.unlock();
        if (!sh.error.empty()) {
          result.error = sh.error;
          play_stop(StreamEnd::kFailed);
        } else {
          result.end = StreamEnd::kComplete;
        }
        break;
      }
      // Nothing (or not enough) planned yet. Before the first row the machine waits at rest.
      if (!o_.realtime || !any) {
        sh.ready.wait(lock);
        continue;
      }
      const long a = ahead();
      if (a <= o_.low_water_periods) {
        if (is_hold(last)) {  // at rest: holding is safe, wait for the planner
          holding = true;
          lock.unlock();
          write(last);
          ++status_.holds;
          lock.lock();
          continue;
        }
        lock.unlock();
        ++status_.underruns;
        play_stop(StreamEnd::kStarved);
        break;
      }
      sh.ready.wait_for(lock, std::chrono::duration<double>(
                                  static_cast<double>(a - o_.low_water_periods) * o_.period_s));
    }
  } catch (...) {
    // The output failed (its reader is gone): the machine got what was written, which the
    // recording keeps, the evidence of how far it went.
    Abort();
    planner.join();
    if (record) {
      record->Commit();
      recorded_ = true;
    }
    throw;
  }
  if (result.end != StreamEnd::kComplete) Abort();
  planner.join();
  try {
    out.Close();
  } catch (...) {
    if (record) {
      record->Commit();
      recorded_ = true;
    }
    throw;
  }

  result.rows = written;
  result.segments = status_.segments_planned;
  result.compute_s = sh.compute_s;
  result.peak_queued = peak;
  result.largest_handover = sh.largest_handover;
  if (any) result.last_q = last.stop && result.stop_rows > 0 ? last.stop->back().q : last.sp.q;
  if (written >= 2) result.verify = verifier.Report();
  result.wall_s = std::chrono::duration<double>(Clock::now() - started).count();
  if (record) {
    record->Commit();
    recorded_ = true;
  }
  return result;
}

}  // namespace dtis::io
