// `dtis serve`: a daemon that feeds one CNC with jobs submitted over a local socket, one after the
// other, each linked from where the previous one left the machine.
//
// Protocol: one JSON object per line on a Unix stream socket (mode 0600; peers of another user are
// refused), one reply line per request:
//   {"cmd":"submit","job":"/abs/job.toml"}  -> {"ok":true,"id":3,"queued":1}
//   {"cmd":"status"}                         -> {"ok":true,"state":"streaming",...}
//   {"cmd":"pause"}   hold at rest at the end of the current segment (pass, link), until "resume"
//   {"cmd":"resume"}
//   {"cmd":"abort"}   stop the current job with its stop to rest; the queue then waits for "resume"
//   {"cmd":"shutdown"} abort, then exit
// A submit is answered once the whole job has been read and checked (curve, program, STEP face,
// passes) on a thread of its own; control requests are answered at once whatever clients, job
// files or jobs do (the control loop never blocks; per-client bounds on what it buffers). A
// malformed request, an unknown command or a job that does not load is answered with
// {"ok":false,"error":"..."} and changes nothing.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "dtis/io/stream.hpp"

namespace dtis::io {

struct ServeOptions {
  std::string socket_path;
  std::string machine_file;  // every job must run on this machine
  kinematics::MachineLoadOptions machine_options;
  StreamOptions stream;    // period comes from each job
  std::string record_dir;  // if set: job-<id>.csv per job, what was streamed
  // When set: where the machine is before the first job (mm, rad).
  std::optional<AxisVector> from;
  // When set: every job is planned with this planner, whatever its [interpolator] planner says.
  std::optional<interp::PlannerKind> planner;
  // When set and true (a signal handler sets it): shut down as "shutdown" does, within 20 ms.
  const std::atomic<bool>* stop = nullptr;
  // Called once the socket listens.
  std::function<void()> listening;
};

// Runs until a "shutdown" request (or `stop`); writes every job's setpoints to `out`. The current
// job ends with its stop to rest and its recording is written; the socket file is removed. Throws
// dtis::Error if the socket cannot be set up: a daemon already answers on the path, or something
// that is not a socket is there (never removed).
void Serve(const ServeOptions& options, CncOutput& out);

// Sends one request line and returns the reply line (for `dtis send` and tests).
std::string SendRequest(const std::string& socket_path, const std::string& request);

}  // namespace dtis::io
