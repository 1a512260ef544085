// The stop signals of `dtis stream` and `dtis serve`: every signal whose default action ends the
// process and that can be caught (SIGKILL cannot; SIGSTOP and SIGTSTP only suspend). Shared by the
// program (cli/main.cpp, which catches them) and its launcher (cli/launcher.cpp, which blocks
// them until the program catches them). No allocation: both use it before anything is set up.
#pragma once

#include <signal.h>

#include <array>

namespace dtis::cli {

inline constexpr int kMaxSignal = 65;  // above SIGRTMAX
// Set by the launcher: the signals it blocked ("2,15,..."), which the program unblocks.
inline constexpr const char* kBlockedByLauncher = "DTIS_BLOCKED_SIGNALS";

// The ones a fault raises: stop signals only when another process sends them.
inline bool IsFaultSignal(int sig) {
  return sig == SIGSEGV || sig == SIGBUS || sig == SIGFPE || sig == SIGILL || sig == SIGTRAP ||
         sig == SIGSYS || sig == SIGABRT;
}

template <typename F>
void ForEachStopSignal(F f) {
  static constexpr std::array kNamed = {SIGHUP,  SIGINT,    SIGQUIT,   SIGTERM, SIGUSR1, SIGUSR2,
                                        SIGPIPE, SIGALRM,   SIGVTALRM, SIGPROF, SIGXCPU, SIGXFSZ,
                                        SIGPOLL, SIGSTKFLT, SIGPWR,    SIGSYS,  SIGTRAP, SIGABRT,
                                        SIGBUS,  SIGFPE,    SIGILL,    SIGSEGV};
  for (const int sig : kNamed) f(sig);
  for (int sig = SIGRTMIN; sig <= SIGRTMAX; ++sig) f(sig);
}

}  // namespace dtis::cli
