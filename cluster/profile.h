// sirad: heterogeneous network emulation (proto/PROTOCOL.md section 8). A profile (YAML) gives
// each node, by name or index, a compute speed factor and its link: latency, jitter, bandwidth
// up and down, loss, and a disconnect at a given time. Coordinator and nodes honour it by
// shaping their own messages through the link model (proto/link_model.h) of the shaped links
// they send on (proto/transport.h ShapedLink).
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "proto/link_model.h"

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
  // The coordinator's own link (key `coordinator`), shared by every node's messages: up_mbit
  // into the coordinator, down_mbit out of it (latency, jitter and loss as for a node). Only
  // the virtual-time cluster (`sirad emulate`) models it; real runs refuse a profile with it.
  std::optional<LinkSpec> coordinator;

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

}  // namespace sirad::emulation
