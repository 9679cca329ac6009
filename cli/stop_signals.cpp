// sirad: SIGINT and SIGTERM set the process's stop flag (see stop_signals.h).
#include "cli/stop_signals.h"

#include <csignal>

namespace sirad::cli {
namespace {

std::atomic<bool> stop{false};
void on_signal(int) { stop = true; }

}  // namespace

const std::atomic<bool>& stop_on_signals() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  return stop;
}

}  // namespace sirad::cli
