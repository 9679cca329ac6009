// sirad: how the long-running programs (sirad-coordinator, its farm, sirad-node) are told to
// stop: SIGINT and SIGTERM set one flag of the process, which their loops watch.
#pragma once
#include <atomic>

namespace sirad::cli {

// Installs the handlers of SIGINT and SIGTERM (again on each call: harmless) and returns the
// flag they set.
const std::atomic<bool>& stop_on_signals();

}  // namespace sirad::cli
