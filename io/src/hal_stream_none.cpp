// The build without LinuxCNC's HAL development files: the native sink says how to get it.
#include "dtis/core/error.hpp"
#include "dtis/io/hal_stream.hpp"

namespace dtis::io {

bool NativeHalBuilt() { return false; }

std::unique_ptr<CncOutput> OpenHalStreamer(int channel, int, bool, long) {
  throw Error(
      "--to hal:{}: this dtis was built without the native HAL sink (install linuxcnc-uspace-dev "
      "and rebuild, or stream through halstreamer: --to FIFO)",
      channel);
}

}  // namespace dtis::io
