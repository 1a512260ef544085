#include "dtis/io/serve.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/io/cancel.hpp"
#include "dtis/io/serve_request.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::io {
namespace {

using json = nlohmann::ordered_json;

// Bounds that keep one client, or a burst of jobs, from taking the daemon over.
constexpr std::size_t kMaxClients = 32;
constexpr std::size_t kMaxLine = std::size_t{1} << 16;    // a request line
constexpr std::size_t kMaxUnsent = std::size_t{1} << 16;  // replies not read yet: read no further
constexpr std::size_t kMaxQueued = 64;                    // jobs waiting, each with its paths read
constexpr int kValidators = 2;  // jobs read at a time: one that takes long delays no other

// A reply as one line of JSON: a message that quotes a file's bytes that are not UTF-8 is sent
// with U+FFFD in their place, never an exception.
std::string Dump(const json& reply) {
  return reply.dump(-1, ' ', false, json::error_handler_t::replace);
}

struct QueuedJob {
  int id = 0;
  Job job;
  std::unique_ptr<SegmentSource> segments;  // built when submitted: every file read and checked
};

struct Finished {
  int id = 0;
  std::string file, end, error;
  long rows = 0, stop_rows = 0;
  double worst_ratio = 0.0;
  bool verified = false;
};

// What the control loop does with a request line: reply at once, or (a submit) have the job
// validated off the control path first, Daemon::Submit giving the reply.
struct Answer {
  std::string reply;
  std::optional<std::string> job_file;
};

// The state shared by the control loop, the validator and the job runner.
class Daemon {
 public:
  Daemon(const ServeOptions& o, CncOutput& out)
      : o_(o),
        out_(out),
        machine_(kinematics::LoadMachineFile(o.machine_file, o.machine_options)),
        at_(o.from) {}

  // Never throws, never waits for more than the daemon's lock, which nothing holds for long.
  Answer Respond(std::string_view line) noexcept {
    try {
      const ServeRequest request = ParseServeRequest(line);
      using Command = ServeRequest::Command;
      if (request.command == Command::kSubmit) return {"", request.job};
      json reply;
      std::unique_lock lock(mutex_);
      switch (request.command) {
        case Command::kStatus:
          reply = Status();
          break;
        case Command::kPause:
          held_ = true;
          if (stream_) stream_->Pause();
          reply = {{"ok", true}};
          break;
        case Command::kResume:
          held_ = false;
          if (stream_) stream_->Resume();
          wake_.notify_all();
          reply = {{"ok", true}};
          break;
        case Command::kAbort:
          held_ = true;  // the queue waits for the operator
          if (stream_) stream_->Abort();
          reply = {{"ok", true}, {"aborted", stream_ != nullptr}};
          break;
        case Command::kShutdown:
          ShutdownLocked();
          reply = {{"ok", true}};
          break;
        case Command::kSubmit:
          break;
      }
      return {Dump(reply), std::nullopt};
    } catch (const Error& e) {
      return {ServeErrorReply(e.what()), std::nullopt};
    } catch (const std::exception& e) {
      return {ServeErrorReply(fmt::format("internal error: {}", e.what())), std::nullopt};
    } catch (...) {
      return {ServeErrorReply("internal error"), std::nullopt};
    }
  }

  // A submit: the job, its machine, and every file it reads (curve, program, STEP face, passes)
  // loaded and checked as the stream will use them, then queued. The reply; never throws.
  // `cancel` (shutdown) ends the reading early, with an error reply.
  std::string Submit(const std::string& file, Cancel* cancel) noexcept {
    json reply;
    try {
      std::lock_guard lock(mutex_);
      ++validating_;
    } catch (...) {
    }
    struct Done {
      Daemon& d;
      ~Done() {
        try {
          std::lock_guard lock(d.mutex_);
          --d.validating_;
        } catch (...) {
        }
      }
    } done{*this};
    try {
      Job job = LoadJob(file);
      if (std::filesystem::weakly_canonical(job.machine_file) !=
          std::filesystem::weakly_canonical(o_.machine_file)) {
        throw Error("{}: runs on {}, this CNC is {}", job.file, job.machine_file, o_.machine_file);
      }
      if (o_.planner) job.vpop.planner = *o_.planner;
      CheckRoom();
      // Refuses what cannot be streamed, a program that runs for more than a job may too.
      auto segments = JobSegments(job, *machine_, std::nullopt, 5.0, cancel);
      std::lock_guard lock(mutex_);
      CheckRoomLocked();
      const int id = ++last_id_;
      queue_.push_back({id, std::move(job), std::move(segments)});
      reply = {{"ok", true}, {"id", id}, {"queued", queue_.size()}};
      if (const std::string notes = queue_.back().segments->Notes(); !notes.empty()) {
        reply["unreachable"] = notes;
      }
      wake_.notify_all();
    } catch (const Error& e) {
      return ServeErrorReply(e.what());
    } catch (const std::exception& e) {
      return ServeErrorReply(fmt::format("internal error: {}", e.what()));
    } catch (...) {
      return ServeErrorReply("internal error");
    }
    try {
      return Dump(reply);
    } catch (...) {
      return ServeErrorReply("internal error: the reply could not be built");
    }
  }

  // The job runner's thread: one job at a time, until shutdown. Nothing escapes it: whatever a job
  // throws is its error in `done`; anything else shuts the daemon down (its job ended at rest).
  void RunJobsCatchingAll() noexcept {
    try {
      RunJobs();
    } catch (...) {
      try {
        std::lock_guard lock(mutex_);
        ShutdownLocked();
      } catch (...) {
      }
    }
  }

 private:
  void RunJobs() {
    for (;;) {
      QueuedJob next;
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [&] { return quit_ || (!held_ && !queue_.empty()); });
        if (quit_) return;
        next = std::move(queue_.front());
        queue_.pop_front();
      }
      Finished f{next.id, next.job.file, "failed", "", 0, 0, 0.0, false};
      try {
        StreamOptions so = o_.stream;
        so.period_s = next.job.vpop.period_s;
        so.commit_horizon = StreamHorizon(next.job);
        next.segments->StartFrom(at_);
        std::optional<SetpointWriter> record;
        if (!o_.record_dir.empty()) {
          record.emplace(fmt::format("{}/job-{}.csv", o_.record_dir, next.id),
                         AxisNames(*machine_));
        }
        Stream stream(*machine_, so);
        {
          std::lock_guard lock(mutex_);
          stream_ = &stream;
          current_ = next.id;
          current_file_ = next.job.file;
          if (held_) stream.Pause();
          if (quit_) stream.Abort();
        }
        StreamResult r;
        try {
          r = stream.Run(*next.segments, out_, record ? &*record : nullptr);
        } catch (const Error& e) {
          {
            std::lock_guard lock(mutex_);
            stream_ = nullptr;
          }
          f.rows = stream.Status().rows;
          // The output failed (its reader died): what was sent is recorded, the evidence.
          if (!stream.Recorded()) throw;
          throw Error("{}; the {} setpoints sent until then are recorded in job-{}.csv", e.what(),
                      f.rows, next.id);
        } catch (...) {
          std::lock_guard lock(mutex_);
          stream_ = nullptr;
          throw;
        }
        {
          std::lock_guard lock(mutex_);
          stream_ = nullptr;
        }
        f.end = StreamEndName(r.end);
        f.error = r.error;
        f.rows = r.rows;
        f.stop_rows = r.stop_rows;
        f.worst_ratio = r.verify.worst_ratio;
        f.verified = r.rows >= 2 && r.verify.Passed();
        if (r.last_q) at_ = r.last_q;
      } catch (const std::exception& e) {
        f.error = e.what();
      } catch (...) {
        f.error = "internal error";
      }
      std::lock_guard lock(mutex_);
      stream_ = nullptr;
      current_ = 0;
      done_.push_back(f);
      if (done_.size() > 100) done_.pop_front();
    }
  }

 public:
  bool Quit() {
    std::lock_guard lock(mutex_);
    return quit_;
  }

  // "shutdown": the current job's stop to rest, then the runner returns.
  void Shutdown() {
    std::lock_guard lock(mutex_);
    ShutdownLocked();
  }

 private:
  void ShutdownLocked() {
    quit_ = true;
    if (stream_) stream_->Abort();
    wake_.notify_all();
  }

  void CheckRoom() {
    std::lock_guard lock(mutex_);
    CheckRoomLocked();
  }
  void CheckRoomLocked() const {
    if (quit_) throw Error("the daemon is shutting down");
    if (queue_.size() >= kMaxQueued) {
      throw Error(
          "{} jobs are queued, the most the daemon holds; submit again once one has started",
          kMaxQueued);
    }
  }

  json Status() const {
    json s = {{"ok", true}};
    s["state"] = stream_ ? (stream_->Paused() ? "pausing" : "streaming") : held_ ? "held" : "idle";
    if (stream_) {
      const StreamStatus& st = stream_->Status();
      s["current"] = {{"id", current_},
                      {"job", current_file_},
                      {"segment", st.segment.load()},
                      {"pass", st.pass.load() + 1},
                      {"s_mm", st.s_mm.load()},
                      {"rows", st.rows.load()},
                      {"queued", st.queued.load()},
                      {"buffer", st.ahead.load()},
                      {"underruns", st.underruns.load()},
                      {"held_rows", st.holds.load()}};
    }
    json queued = json::array();
    for (const auto& q : queue_) queued.push_back({{"id", q.id}, {"job", q.job.file}});
    s["queue"] = queued;
    s["validating"] = validating_;
    json done = json::array();
    for (const auto& f : done_) {
      done.push_back({{"id", f.id},
                      {"job", f.file},
                      {"end", f.end},
                      {"error", f.error},
                      {"rows", f.rows},
                      {"stop_rows", f.stop_rows},
                      {"worst_ratio", f.worst_ratio},
                      {"verified", f.verified}});
    }
    s["done"] = done;
    return s;
  }

  const ServeOptions& o_;
  CncOutput& out_;
  std::unique_ptr<Machine> machine_;
  std::optional<AxisVector> at_;  // where the last job left the machine (runner thread only)
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<QueuedJob> queue_;
  std::deque<Finished> done_;
  Stream* stream_ = nullptr;
  int current_ = 0;
  std::string current_file_;
  int last_id_ = 0;
  int validating_ = 0;  // submitted jobs being read
  bool held_ = false, quit_ = false;
};

sockaddr_un Address(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof(addr.sun_path)) {
    throw Error("socket path '{}' is longer than {} characters", path, sizeof(addr.sun_path) - 1);
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return addr;
}

// A peer of the same user (or root) only.
bool SameUser(int fd) {
  ucred cred{};
  socklen_t len = sizeof(cred);
  if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return false;
  return cred.uid == getuid() || cred.uid == 0;
}

// Clears the way for a new socket at `path`: nothing there, or a socket no daemon answers on any
// more (left by one that was killed), which is removed. A live daemon's socket and anything that
// is not a socket are left alone: an error.
void ClaimSocketPath(const std::string& path) {
  struct stat st {};
  if (lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return;
    throw Error("{}: cannot check the socket path: {}", path, std::strerror(errno));
  }
  if (!S_ISSOCK(st.st_mode)) {
    throw Error("{}: exists and is not a socket; not removing it (choose another --socket)", path);
  }
  const sockaddr_un addr = Address(path);
  const int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (probe < 0) throw Error("socket: {}", std::strerror(errno));
  const int connected = connect(probe, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  const int why = errno;
  ::close(probe);
  if (connected == 0) {
    throw Error(
        "{}: another dtis serve is listening there (dtis send '{{\"cmd\":\"shutdown\"}}' "
        "ends it)",
        path);
  }
  if (why != ECONNREFUSED) {
    throw Error("{}: cannot tell whether a daemon listens there: {}", path, std::strerror(why));
  }
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) {
    throw Error("{}: cannot remove the stale socket: {}", path, std::strerror(errno));
  }
}

// Validates submitted jobs on kValidators threads of their own, at a lower CPU priority than the
// stream's planner (a job being read must never make the running one underrun), and hands the
// replies back to the control loop, waking its poll. A job that takes long to read (a program
// that runs until its 24 h bound) holds one thread, not the others, and never the control loop;
// shutdown cancels whatever is being read.
class Validator {
 public:
  explicit Validator(Daemon& daemon) : daemon_(daemon) {
    if (pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0) {
      throw Error("dtis serve: pipe: {}", std::strerror(errno));
    }
    try {
      for (int k = 0; k < kValidators; ++k) threads_.emplace_back([this] { Run(); });
    } catch (...) {
      Stop();
      throw;
    }
  }
  ~Validator() { Stop(); }
  // Waits for the workers to end, once CancelAll was called.
  void Join() noexcept {
    for (auto& t : threads_) {
      if (t.joinable()) t.join();
    }
  }
  Validator(const Validator&) = delete;
  Validator& operator=(const Validator&) = delete;

  void Add(std::uint64_t client, std::string job_file) {
    {
      std::lock_guard lock(mutex_);
      todo_.push_back({client, std::move(job_file)});
    }
    todo_ready_.notify_all();
  }
  // Ends every read under way (each gets an error reply) and takes no more.
  void CancelAll(const std::string& why) {
    std::lock_guard lock(mutex_);
    quit_ = true;
    for (const auto& cancel : reading_) cancel->Request(why);
    for (const auto& [client, file] : todo_) replies_.emplace_back(client, ServeErrorReply(why));
    todo_.clear();
    todo_ready_.notify_all();
  }
  // Readable when replies are ready.
  int WakeFd() const { return wake_[0]; }
  // The replies ready, by client.
  std::vector<std::pair<std::uint64_t, std::string>> TakeReplies() {
    char drain[64];
    while (::read(wake_[0], drain, sizeof(drain)) > 0) {
    }
    std::lock_guard lock(mutex_);
    return std::exchange(replies_, {});
  }

 private:
  void Stop() noexcept {
    try {
      CancelAll("the daemon is shutting down");
    } catch (...) {
    }
    Join();
    ::close(wake_[0]);
    ::close(wake_[1]);
  }
  // A worker's thread: nothing escapes it (a reply per job, an error if need be).
  void Run() noexcept {
    setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 10);  // best effort
    for (;;) {
      try {
        std::pair<std::uint64_t, std::string> next;
        auto cancel = std::make_shared<Cancel>();
        {
          std::unique_lock lock(mutex_);
          todo_ready_.wait(lock, [&] { return quit_ || !todo_.empty(); });
          if (quit_) return;
          next = std::move(todo_.front());
          todo_.pop_front();
          reading_.insert(cancel);
        }
        std::string reply = daemon_.Submit(next.second, cancel.get());
        {
          std::lock_guard lock(mutex_);
          reading_.erase(cancel);
          replies_.emplace_back(next.first, std::move(reply));
        }
        (void)!::write(wake_[1], "r", 1);
      } catch (...) {
        // Out of memory for a reply: that client waits no more than the others do.
      }
    }
  }

  Daemon& daemon_;
  int wake_[2] = {-1, -1};
  std::mutex mutex_;
  std::condition_variable todo_ready_;
  std::deque<std::pair<std::uint64_t, std::string>> todo_;
  std::set<std::shared_ptr<Cancel>> reading_;
  std::vector<std::pair<std::uint64_t, std::string>> replies_;
  bool quit_ = false;
  std::vector<std::thread> threads_;
};

// One connection. Its requests are answered in order: while its submit is validated, its next
// lines wait; while it leaves kMaxUnsent bytes of replies unread, it is read no further (its own
// writes then block, nobody else's).
struct Client {
  std::uint64_t serial = 0;
  int fd = -1;
  std::string in, out;
  bool validating = false;
  bool eof = false;  // the peer sent everything it will send
  // After a line over kMaxLine: what it sends is read and dropped (closing with input unread would
  // reset the connection, and the peer might lose the error), until it closes, kMaxDrained bytes
  // or kMaxDraining, whichever comes first.
  bool discard = false;
  std::size_t drained = 0;
  std::chrono::steady_clock::time_point discard_since{};
  static constexpr std::size_t kMaxDrained = std::size_t{1} << 20;
  static constexpr std::chrono::seconds kMaxDraining{5};

  bool Readable() const { return !eof && (discard || (!validating && out.size() < kMaxUnsent)); }
  bool Done() const {
    return fd < 0 || (eof && !validating && out.empty()) ||
           (discard && out.empty() &&
            (drained > kMaxDrained ||
             std::chrono::steady_clock::now() - discard_since > kMaxDraining));
  }

  // Sends what it can without waiting; a peer gone closes the connection.
  void Flush() {
    while (fd >= 0 && !out.empty()) {
      const ssize_t n = ::send(fd, out.data(), out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) {
        out.erase(0, static_cast<std::size_t>(n));
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
        return;
      } else {
        Close();
      }
    }
  }
  void Close() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
};

// Answers the complete lines a client has sent, as far as its order and limits allow.
void HandleLines(Client& c, Daemon& daemon, Validator& validator) {
  for (std::size_t eol; c.fd >= 0 && !c.validating && c.out.size() < kMaxUnsent &&
                        (eol = c.in.find('\n')) != std::string::npos;) {
    Answer a = daemon.Respond(c.in.substr(0, eol));
    c.in.erase(0, eol + 1);
    if (a.job_file) {
      c.validating = true;
      validator.Add(c.serial, std::move(*a.job_file));
    } else {
      c.out += a.reply + "\n";
    }
  }
  c.Flush();
}

// Reads what a client sent, without waiting.
void ReadFrom(Client& c) {
  char buf[4096];
  const ssize_t n = ::recv(c.fd, buf, sizeof(buf), MSG_DONTWAIT);
  if (n == 0) {
    c.eof = true;
  } else if (n < 0) {
    if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) c.Close();
  } else if (c.discard) {
    c.drained += static_cast<std::size_t>(n);
  } else {
    c.in.append(buf, static_cast<std::size_t>(n));
    if (c.in.size() > kMaxLine && c.in.find('\n') == std::string::npos) {
      c.out += R"({"ok":false,"error":"request longer than 64 KiB"})"
               "\n";
      c.in.clear();
      c.discard = true;  // answer nothing more; end once the error is sent
      c.discard_since = std::chrono::steady_clock::now();
    }
  }
}

// The control loop: it never blocks on a client, a job file or a job, so that status, pause
// and abort are answered within a poll round, whatever else happens. Returns on shutdown.
void ControlLoop(const ServeOptions& options, int listener, Daemon& daemon, Validator& validator,
                 std::vector<Client>& clients) {
  std::uint64_t serial = 0;
  while (!daemon.Quit()) {
    if (options.stop && *options.stop) {
      daemon.Shutdown();
      break;
    }
    std::vector<pollfd> fds{{listener, POLLIN, 0}, {validator.WakeFd(), POLLIN, 0}};
    for (const auto& c : clients) {
      const short events =
          static_cast<short>((c.Readable() ? POLLIN : 0) | (c.out.empty() ? 0 : POLLOUT));
      // A client neither read nor written is not polled (a hang-up would wake the poll at once).
      fds.push_back({events != 0 ? c.fd : -1, events, 0});
    }
    if (poll(fds.data(), fds.size(), 20) < 0 && errno != EINTR) break;
    for (std::size_t k = 0; k < clients.size(); ++k) {
      Client& c = clients[k];
      const short got = fds[k + 2].revents;
      if (got & POLLOUT) c.Flush();
      if (c.fd >= 0 && (got & (POLLIN | POLLHUP | POLLERR)) && c.Readable()) ReadFrom(c);
      if (c.fd >= 0 && (got & POLLERR)) c.Close();
      HandleLines(c, daemon, validator);
      if (c.discard && c.out.empty() && c.fd >= 0) ::shutdown(c.fd, SHUT_WR);  // the error is out
    }
    if (fds[1].revents & POLLIN) {
      for (auto& [to, reply] : validator.TakeReplies()) {
        for (auto& c : clients) {
          if (c.serial != to) continue;
          c.validating = false;
          c.out += reply + "\n";
          HandleLines(c, daemon, validator);
        }
      }
    }
    if (fds[0].revents & POLLIN) {
      for (int fd; (fd = accept4(listener, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK)) >= 0;) {
        if (!SameUser(fd)) {
          ::close(fd);
        } else if (clients.size() >= kMaxClients) {
          const std::string busy = fmt::format(
              R"({{"ok":false,"error":"{} clients are connected, the most the daemon serves"}})"
              "\n",
              kMaxClients);
          (void)!::send(fd, busy.data(), busy.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
          ::close(fd);
        } else {
          clients.push_back({++serial, fd, {}, {}, false, false});
        }
      }
    }
    for (auto& c : clients) {
      if (c.Done()) c.Close();
    }
    std::erase_if(clients, [](const Client& c) { return c.fd < 0; });
  }
}

}  // namespace

void Serve(const ServeOptions& options, CncOutput& out) {
  Daemon daemon(options, out);
  const sockaddr_un addr = Address(options.socket_path);
  ClaimSocketPath(options.socket_path);
  const int listener = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (listener < 0) throw Error("socket: {}", std::strerror(errno));
  const mode_t old_mask = umask(0077);  // the socket file is the owner's only
  const int bound = bind(listener, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  umask(old_mask);
  if (bound != 0 || chmod(options.socket_path.c_str(), 0600) != 0 || listen(listener, 8) != 0) {
    const std::string why = std::strerror(errno);
    ::close(listener);
    throw Error("{}: cannot listen: {}", options.socket_path, why);
  }
  // From here on, whatever happens ends the same way: the current job's stop to rest, its
  // recording written, the socket removed, every thread joined.
  std::string failure;
  std::vector<Client> clients;
  std::optional<std::thread> runner;
  std::optional<Validator> validator;
  try {
    runner.emplace([&] { daemon.RunJobsCatchingAll(); });
    validator.emplace(daemon);
    if (options.listening) options.listening();
    ControlLoop(options, listener, daemon, *validator, clients);
  } catch (const std::exception& e) {
    failure = e.what();
  } catch (...) {
    failure = "unknown exception";
  }
  daemon.Shutdown();
  ::close(listener);
  ::unlink(options.socket_path.c_str());
  if (validator) validator->CancelAll("the daemon is shutting down");
  if (runner) runner->join();
  if (validator) {
    // The reads just cancelled end soon: their clients get the error, as far as they read it.
    validator->Join();
    for (auto& [to, reply] : validator->TakeReplies()) {
      for (auto& c : clients) {
        if (c.serial == to) c.out += reply + "\n";
      }
    }
  }
  for (auto& c : clients) {
    c.Flush();
    c.Close();
  }
  validator.reset();
  if (!failure.empty()) {
    throw Error("dtis serve: internal error ({}); the machine was brought to rest", failure);
  }
}

std::string SendRequest(const std::string& socket_path, const std::string& request) {
  const sockaddr_un addr = Address(socket_path);
  const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw Error("socket: {}", std::strerror(errno));
  if (connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    throw Error("{}: cannot connect: {} (is `dtis serve` running?)", socket_path, why);
  }
  const std::string line = request + "\n";
  if (::write(fd, line.data(), line.size()) != static_cast<ssize_t>(line.size())) {
    ::close(fd);
    throw Error("{}: cannot send the request", socket_path);
  }
  std::string reply;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n <= 0) break;
    reply.append(buf, static_cast<std::size_t>(n));
    if (reply.find('\n') != std::string::npos) break;
  }
  ::close(fd);
  if (reply.empty()) throw Error("{}: no reply", socket_path);
  if (reply.back() == '\n') reply.pop_back();
  return reply;
}

}  // namespace dtis::io
