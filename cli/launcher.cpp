// `dtis` as users run it: blocks the stop signals, then runs the program itself (dtis-main, next
// to it) in its place. Between exec and dtis-main's first instruction the dynamic loader maps and
// relocates its libraries (OpenCASCADE's among them: 20 ms on an idle machine, 100-200 ms on a
// busy one); a stop signal that comes meanwhile now waits, pending, until dtis-main catches it
// and unblocks it (cli/main.cpp), instead of ending it with its default action. Linked
// statically: nothing is loaded before the signals are blocked. docs/streaming.md#signals.
#include <limits.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "stop_signals.hpp"

int main(int argc, char** argv) {
  (void)argc;
  // Blocks the stop signals the parent left unblocked, and tells dtis-main which: it unblocks
  // those once it catches them, and leaves the parent's own mask as it was.
  sigset_t stop, old;
  sigemptyset(&stop);
  dtis::cli::ForEachStopSignal([&](int sig) { sigaddset(&stop, sig); });
  sigprocmask(SIG_BLOCK, &stop, &old);
  char blocked[3 * dtis::cli::kMaxSignal + 1] = "";
  std::size_t used = 0;
  dtis::cli::ForEachStopSignal([&](int sig) {
    if (sigismember(&old, sig) == 0 && used + 4 < sizeof blocked) {
      used += static_cast<std::size_t>(
          std::snprintf(blocked + used, sizeof blocked - used, "%s%d", used ? "," : "", sig));
    }
  });
  setenv(dtis::cli::kBlockedByLauncher, blocked, 1);

  char path[PATH_MAX];
  const ssize_t n = readlink("/proc/self/exe", path, sizeof path - 1);
  const char* const program = "dtis-main";
  if (n > 0) {
    path[n] = '\0';
    char* slash = std::strrchr(path, '/');
    if (slash != nullptr && (slash - path) + 1 + std::strlen(program) < sizeof path) {
      std::strcpy(slash + 1, program);
      execv(path, argv);
    }
  }
  const int why = errno;
  sigprocmask(SIG_SETMASK, &old, nullptr);
  std::fprintf(stderr,
               "dtis: cannot run %s: %s (dtis starts the program %s installed beside it: copy "
               "or install both)\n",
               n > 0 ? path : program, std::strerror(why), program);
  return 4;
}
