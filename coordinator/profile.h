// sirad: heterogeneous network emulation (proto/PROTOCOL.md section 8). A profile (YAML) gives
// each node, by name or index, a compute speed factor and its link: latency, jitter, bandwidth
// up and down, loss, and a disconnect at a given time. Coordinator and nodes honour it by
// shaping their own messages through LinkModel, a plain model of one direction of a TCP link
// with time passed in (no clocks, no sockets here): the delay queues live in proto/transport.h.
#pragma once
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace sirad::emulation {

// What the profile says about one node and its link. Rates of 0 mean "not limited".
struct LinkSpec {
  double speed = 1.0;             // compute speed factor (see Profile::slowdown)
  double latency_ms = 0;          // one-way delay of every message
  double jitter_ms = 0;           // the delay varies uniformly in latency +- jitter (>= 0)
  double up_mbit = 0;             // node -> coordinator bandwidth, Mbit/s
  double down_mbit = 0;           // coordinator -> node bandwidth, Mbit/s
  double loss = 0;                // packet loss probability in [0, 0.5]
  double disconnect_at_s = -1;    // seconds after it is ready in a run the node drops off (< 0: never)
  double reconnect_after_s = -1;  // and comes back this much later (< 0: not in this process)
  bool shaped() const { return latency_ms > 0 || jitter_ms > 0 || up_mbit > 0 || down_mbit > 0 || loss > 0; }
  bool operator==(const LinkSpec&) const = default;
};

struct Profile {
  std::string name;
  LinkSpec defaults;   // nodes no entry matches
  struct Entry {
    std::optional<uint32_t> index;  // the node's join index in the run
    std::optional<std::string> name;
    LinkSpec spec;                  // the defaults with this entry's keys over them
  };
  std::vector<Entry> nodes;

  // The first entry, in file order, whose name or index matches; else the defaults.
  LinkSpec for_node(uint32_t index, const std::string& name) const;
  // One machine cannot run faster than itself, so speeds are relative to the profile's fastest:
  // a node of speed f takes max_speed / f times its real time per bundle (1 for the fastest).
  double slowdown(const LinkSpec& spec) const;
  double max_speed() const;
};

// Parses a profile; every error is one line naming `origin`, the line and the key
// ("office.yaml:12: nodes[1].loss: 0.7 is not in [0, 0.5]"). Unknown keys are errors.
Profile parse_profile(const std::string& text, const std::string& origin);
// Reads and parses a profile file (sirad::Error naming the file if it cannot be read).
Profile load_profile(const std::string& path);

// The seed of node `index`'s emulated links in a run of `seed` (downlink; the uplink: + 1).
inline uint64_t link_seed(uint64_t seed, uint32_t index) { return seed * 0x9E3779B97F4A7C15ull + index; }

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
