// sirad: one direction of an emulated TCP link (see link_model.h).
#include "proto/link_model.h"

#include <algorithm>
#include <cmath>

namespace sirad::emulation {

LinkModel::LinkModel(double mbit, double latency_ms, double jitter_ms, double loss, uint64_t seed)
    : shaped_(mbit > 0 || latency_ms > 0 || jitter_ms > 0 || loss > 0), bits_per_s_(mbit * 1e6),
      latency_(latency_ms * 1e-3), jitter_(jitter_ms * 1e-3), loss_(loss), rng_(seed) {
  // With loss, TCP's throughput is also bounded by its congestion control (Mathis et al. 1997:
  // rate <= 1.22 MSS / (RTT sqrt(p))), the tighter bound on long lossy links.
  double rtt = 2 * latency_;
  if (loss_ > 0 && rtt > 0) {
    double mathis = 1.22 * kSegmentBytes * 8 / (rtt * std::sqrt(loss_));
    bits_per_s_ = bits_per_s_ > 0 ? std::min(bits_per_s_, mathis) : mathis;
  }
}

double LinkModel::deliver(double now, std::size_t bytes) {
  if (!shaped_) return now;
  double start = std::max(now, busy_until_);
  busy_until_ = bits_per_s_ > 0 ? start + 8.0 * static_cast<double>(bytes) / bits_per_s_ : start;
  double delay = latency_;
  if (jitter_ > 0) delay = std::max(0.0, delay + std::uniform_real_distribution<double>(-jitter_, jitter_)(rng_));
  // Loss: every packet is lost with probability p, independently, and sent again; the message
  // is complete after the slowest packet's last round. A round costs an RTT when the message
  // is long enough for fast retransmit (3 duplicate ACKs), else a retransmission timeout.
  if (loss_ > 0) {
    uint64_t left = std::max<uint64_t>(1, (bytes + kSegmentBytes - 1) / kSegmentBytes);
    double round = left > 3 ? std::max(2 * latency_, 1e-3) : std::max(kMinRto, 2 * latency_);
    while (left > 0) {
      left = std::binomial_distribution<uint64_t>(left, loss_)(rng_);
      if (left > 0) delay += round;
    }
  }
  last_arrival_ = std::max(last_arrival_, busy_until_ + delay);  // TCP keeps the order
  return last_arrival_;
}

}  // namespace sirad::emulation
