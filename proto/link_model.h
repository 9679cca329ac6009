// sirad: the model of one direction of an emulated TCP link (PROTOCOL.md section 8), with time
// passed in: no clocks, no sockets. The shaped links of the transport (proto/transport.h
// ShapedLink), the real coordinator and node, and the virtual-time cluster all use it.
#pragma once
#include <cstddef>
#include <cstdint>
#include <random>

namespace sirad::emulation {

// One direction of an emulated TCP link: messages leave in order through a server of the
// link's bandwidth (store and forward), then take the latency with jitter; a lost packet costs
// a retransmission timeout (TCP delivers everything, late) and messages never overtake each
// other. Deterministic for a seed. Times are seconds on the caller's clock.
class LinkModel {
 public:
  LinkModel() = default;  // unshaped: every message arrives when sent
  LinkModel(double mbit, double latency_ms, double jitter_ms, double loss, uint64_t seed);
  // When a message of `bytes` sent at `now` arrives.
  double deliver(double now, std::size_t bytes);
  bool shaped() const { return shaped_; }

  static constexpr std::size_t kSegmentBytes = 1448;  // TCP payload per packet (Ethernet MTU)
  static constexpr double kMinRto = 0.2;               // Linux's minimum retransmission timeout

 private:
  bool shaped_ = false;
  double bits_per_s_ = 0, latency_ = 0, jitter_ = 0, loss_ = 0;
  double busy_until_ = 0, last_arrival_ = 0;
  std::mt19937_64 rng_;
};

}  // namespace sirad::emulation
