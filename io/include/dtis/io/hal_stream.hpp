// The native LinuxCNC sink: setpoints written straight into a HAL `streamer` component's
// shared-memory FIFO through the HAL stream API (hal_stream(3)), with no text and no halstreamer
// in between. Built when LinuxCNC's HAL development files are found (linuxcnc-uspace-dev; CMake
// option DTIS_WITH_HAL); otherwise opening it is an error that says so.
#pragma once

#include <memory>

#include "dtis/io/stream.hpp"

namespace dtis::io {

// Whether this build has the native HAL sink.
bool NativeHalBuilt();

// Attaches to `streamer.<channel>` of the running HAL session (loadrt streamer cfg=...): its pins
// must be `axes` floats, plus one u32 when `index_column` (the row number + 1, as
// HalstreamerOutput writes it). Queued() is the FIFO's depth, so a real-time stream keeps exactly
// its buffer in the machine. Throws a clear error when no HAL session runs, the streamer is
// missing, its pins do not match or it is smaller than `buffer_periods` + 1.
std::unique_ptr<CncOutput> OpenHalStreamer(int channel, int axes, bool index_column,
                                           long buffer_periods);

}  // namespace dtis::io
