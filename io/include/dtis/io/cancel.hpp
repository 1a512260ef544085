// Giving up a long read from another thread: `dtis serve` cancels the jobs it is validating when
// it shuts down. A reader checks Requested() between steps, and registers an action for a step
// that may block (LinuxCNC's interpreter, a child process that may run without writing: killed).
#pragma once

#include <atomic>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <utility>

#include "dtis/core/error.hpp"

namespace dtis::io {

class Cancel {
 public:
  // Asks whatever reads with this token to stop, with the reason its error will carry; runs the
  // registered actions. The first reason is kept.
  void Request(const std::string& why) {
    std::lock_guard lock(mutex_);
    if (requested_) return;
    why_ = why;
    requested_ = true;
    for (auto& [id, action] : actions_) action();
  }
  bool Requested() const { return requested_.load(); }
  // Throws dtis::Error with the reason, once requested.
  void ThrowIfRequested() const {
    if (!requested_) return;
    std::lock_guard lock(mutex_);
    throw Error("{}", why_);
  }

  // Runs `action` (which must not throw) when cancel is requested, at once if it already was,
  // until the hook is destroyed; an action never runs after its hook's destructor returned.
  class Hook {
   public:
    Hook() = default;
    Hook(Cancel* cancel, std::function<void()> action) : cancel_(cancel) {
      if (cancel_ != nullptr) id_ = cancel_->Add(std::move(action));
    }
    ~Hook() { Reset(); }
    Hook(Hook&& o) noexcept : cancel_(std::exchange(o.cancel_, nullptr)), id_(o.id_) {}
    Hook& operator=(Hook&& o) noexcept {
      if (this != &o) {
        Reset();
        cancel_ = std::exchange(o.cancel_, nullptr);
        id_ = o.id_;
      }
      return *this;
    }
    void Reset() {
      if (Cancel* c = std::exchange(cancel_, nullptr)) c->Remove(id_);
    }

   private:
    Cancel* cancel_ = nullptr;
    long id_ = 0;
  };

 private:
  long Add(std::function<void()> action) {
    std::lock_guard lock(mutex_);
    if (requested_) action();
    actions_.emplace(++last_id_, std::move(action));
    return last_id_;
  }
  void Remove(long id) {
    std::lock_guard lock(mutex_);
    actions_.erase(id);
  }

  mutable std::mutex mutex_;
  std::atomic<bool> requested_{false};
  std::string why_;
  std::map<long, std::function<void()>> actions_;
  long last_id_ = 0;
};

}  // namespace dtis::io
