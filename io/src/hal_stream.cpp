// Built only with DTIS_WITH_HAL (see io/CMakeLists.txt); hal_stream_none.cpp stands in otherwise.
#include "dtis/io/hal_stream.hpp"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <string>
#include <thread>

#include "dtis/core/error.hpp"

// LinuxCNC's HAL, as a non-realtime (ULAPI) component.
#define ULAPI 1
#include <hal.h>

namespace dtis::io {
namespace {

// halstreamer's key for streamer channel N (hal_stream(3)).
constexpr int kStreamerKey = 0x48535430;
// How long a full FIFO may stay full before the HAL thread is taken for stopped.
constexpr auto kStalled = std::chrono::seconds(5);

class HalStreamerSink final : public CncOutput {
 public:
  HalStreamerSink(int channel, int axes, bool index_column, long buffer_periods)
      : channel_(channel),
        axes_(axes),
        index_column_(index_column),
        cfg_(std::string(static_cast<std::size_t>(axes), 'f') + (index_column ? "u" : "")) {
    const std::string name = "dtis-stream-" + std::to_string(getpid());
    comp_ = hal_init(name.c_str());
    if (comp_ < 0) {
      throw Error("HAL: cannot register component '{}' (error {}): is a HAL session running?", name,
                  comp_);
    }
    const int rc = hal_stream_attach(&stream_, comp_, kStreamerKey + channel, nullptr);
    if (rc < 0) {
      hal_exit(comp_);
      throw Error(
          "HAL: no streamer.{} to attach to (error {}): load it first, e.g. 'loadrt streamer "
          "depth=1021 cfg={}'",
          channel, rc, cfg_);
    }
    try {
      CheckPins(buffer_periods);
      hal_ready(comp_);
    } catch (...) {
      hal_stream_detach(&stream_);
      hal_exit(comp_);
      throw;
    }
  }
  ~HalStreamerSink() override {
    hal_stream_detach(&stream_);
    hal_exit(comp_);
  }
  HalStreamerSink(const HalStreamerSink&) = delete;
  HalStreamerSink& operator=(const HalStreamerSink&) = delete;

  void Write(const StreamRow& row) override {
    hal_stream_data data[kMaxAxes + 1];
    for (int i = 0; i < axes_; ++i) data[i].f = row.q[i];
    if (index_column_) data[axes_].u = static_cast<std::uint32_t>(row.row + 1);
    const auto since = std::chrono::steady_clock::now();
    while (!hal_stream_writable(&stream_)) {
      // Full: the machine plays one row per period; wait for room.
      if (std::chrono::steady_clock::now() - since > kStalled) {
        throw Error("HAL: streamer.{}'s FIFO stayed full for {} s: is its thread running?",
                    channel_, kStalled.count());
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (hal_stream_write(&stream_, data) != 0) {
      throw Error("HAL: cannot write row {} into streamer.{}", row.row, channel_);
    }
  }
  std::optional<long> Queued() const override {
    return hal_stream_depth(const_cast<hal_stream_t*>(&stream_));
  }

 private:
  void CheckPins(long buffer_periods) {
    const int want = axes_ + (index_column_ ? 1 : 0);
    std::string have;
    const int count = hal_stream_element_count(&stream_);
    for (int i = 0; i < count; ++i) {
      switch (hal_stream_element_type(&stream_, i)) {
        case HAL_FLOAT:
          have += 'f';
          break;
        case HAL_U32:
          have += 'u';
          break;
        case HAL_S32:
          have += 's';
          break;
        case HAL_BIT:
          have += 'b';
          break;
        default:
          have += '?';
      }
    }
    if (count != want || have != cfg_) {
      throw Error("HAL: streamer.{} has pins cfg={}; this machine needs cfg={}{}", channel_, have,
                  cfg_, index_column_ ? " (--index adds the u32)" : "");
    }
    const long depth = hal_stream_maxdepth(&stream_);
    if (depth <= buffer_periods) {
      throw Error(
          "HAL: streamer.{} holds {} rows, not more than the buffer of {} periods: load "
          "it with a larger depth or pass a smaller --buffer",
          channel_, depth, buffer_periods);
    }
  }

  int channel_;
  int axes_;
  bool index_column_;
  std::string cfg_;  // the streamer's pins this machine needs: one f per axis, u for the index
  int comp_ = -1;
  hal_stream_t stream_{};
};

}  // namespace

bool NativeHalBuilt() { return true; }

std::unique_ptr<CncOutput> OpenHalStreamer(int channel, int axes, bool index_column,
                                           long buffer_periods) {
  if (axes < 1 || axes > kMaxAxes) throw Error("HAL: {} axes is not a machine", axes);
  return std::make_unique<HalStreamerSink>(channel, axes, index_column, buffer_periods);
}

}  // namespace dtis::io
