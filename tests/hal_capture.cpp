// Test tool: records what HAL's sampler.N captured, every period, at full precision (halsampler
// prints 6 decimals, too coarse to compare a stream with its plan or to take a jerk from).
// Usage: hal_capture CHANNEL > capture.txt ; stops on SIGINT/SIGTERM after draining the FIFO.
// One line per sample: the pins in order, floats as shortest round-trip decimals.
#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#define ULAPI 1
#include <hal.h>

namespace {

constexpr int kSamplerKey = 0x48534130;  // halsampler's key for sampler channel N
volatile sig_atomic_t g_stop = 0;
extern "C" void OnStop(int) { g_stop = 1; }

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: hal_capture CHANNEL\n");
    return 2;
  }
  const int channel = std::atoi(argv[1]);
  const std::string name = "dtis-capture-" + std::to_string(getpid());
  const int comp = hal_init(name.c_str());
  if (comp < 0) {
    std::fprintf(stderr, "hal_capture: hal_init failed (%d)\n", comp);
    return 1;
  }
  hal_stream_t stream{};
  if (hal_stream_attach(&stream, comp, kSamplerKey + channel, nullptr) < 0) {
    std::fprintf(stderr, "hal_capture: no sampler.%d\n", channel);
    hal_exit(comp);
    return 1;
  }
  hal_ready(comp);
  std::signal(SIGINT, OnStop);
  std::signal(SIGTERM, OnStop);
  const int n = hal_stream_element_count(&stream);
  std::vector<hal_type_t> types(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i)
    types[static_cast<std::size_t>(i)] = hal_stream_element_type(&stream, i);
  std::vector<hal_stream_data> row(static_cast<std::size_t>(n));
  fmt::memory_buffer line;
  long samples = 0;
  for (;;) {
    if (!hal_stream_readable(&stream)) {
      if (g_stop) break;  // drained
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      continue;
    }
    if (hal_stream_read(&stream, row.data(), nullptr) != 0) break;
    line.clear();
    for (std::size_t i = 0; i < row.size(); ++i) {
      if (i) line.push_back(' ');
      switch (types[i]) {
        case HAL_FLOAT:
          fmt::format_to(std::back_inserter(line), "{}", static_cast<double>(row[i].f));
          break;
        case HAL_BIT:
          fmt::format_to(std::back_inserter(line), "{}", row[i].b ? 1 : 0);
          break;
        case HAL_S32:
          fmt::format_to(std::back_inserter(line), "{}", row[i].s);
          break;
        default:
          fmt::format_to(std::back_inserter(line), "{}", row[i].u);
      }
    }
    line.push_back('\n');
    std::fwrite(line.data(), 1, line.size(), stdout);
    ++samples;
  }
  const int overruns = hal_stream_num_overruns(&stream);
  hal_stream_detach(&stream);
  hal_exit(comp);
  std::fprintf(stderr, "hal_capture: %ld samples, %d overruns\n", samples, overruns);
  return std::fflush(stdout) == 0 && overruns == 0 ? 0 : 1;
}
