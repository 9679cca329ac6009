// sirad: network-emulation profiles (YAML) and the link model.
#include "coordinator/profile.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "core/atomic_file.h"
#include "core/error.h"

namespace sirad::emulation {

namespace {

// "FILE:LINE: what" for a node of the document (yaml-cpp marks are 0-based).
std::string where(const std::string& origin, const YAML::Node& node) {
  return node.Mark().is_null() ? origin : fmt::format("{}:{}", origin, node.Mark().line + 1);
}

double number(const std::string& origin, const std::string& key, const YAML::Node& node, double lo, double hi) {
  double v = 0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    fail("{}: {}: expected a number, got '{}'", where(origin, node), key, node.IsScalar() ? node.Scalar() : "a list or map");
  }
  if (!std::isfinite(v) || v < lo || v > hi) fail("{}: {}: {} is not in [{}, {}]", where(origin, node), key, node.Scalar(), lo, hi);
  return v;
}

// The link keys of `map` over `spec`; anything else in the map is an error unless in `extra`.
void apply(const std::string& origin, const std::string& path, const YAML::Node& map, LinkSpec& spec,
           const std::vector<std::string>& extra) {
  if (!map.IsMap()) fail("{}: {}: expected a map of settings", where(origin, map), path);
  for (const auto& kv : map) {
    std::string key = kv.first.as<std::string>();
    const YAML::Node& v = kv.second;
    std::string name = path.empty() ? key : fmt::format("{}.{}", path, key);
    if (key == "speed") spec.speed = number(origin, name, v, 1e-3, 1e3);
    else if (key == "latency_ms") spec.latency_ms = number(origin, name, v, 0, 60000);
    else if (key == "jitter_ms") spec.jitter_ms = number(origin, name, v, 0, 60000);
    else if (key == "bandwidth_mbit") spec.up_mbit = spec.down_mbit = number(origin, name, v, 1e-3, 1e6);
    else if (key == "up_mbit") spec.up_mbit = number(origin, name, v, 1e-3, 1e6);
    else if (key == "down_mbit") spec.down_mbit = number(origin, name, v, 1e-3, 1e6);
    else if (key == "loss") spec.loss = number(origin, name, v, 0, 0.5);
    else if (key == "disconnect_at_s") spec.disconnect_at_s = number(origin, name, v, 0, 1e7);
    else if (key == "reconnect_after_s") spec.reconnect_after_s = number(origin, name, v, 0, 1e7);
    else if (std::find(extra.begin(), extra.end(), key) == extra.end())
      fail("{}: {}: unknown key (known: speed, latency_ms, jitter_ms, bandwidth_mbit, up_mbit, down_mbit, loss, "
           "disconnect_at_s, reconnect_after_s{})",
           where(origin, kv.first), name, path.rfind("nodes", 0) == 0 ? ", name, index" : "");
  }
  if (spec.reconnect_after_s >= 0 && spec.disconnect_at_s < 0)
    fail("{}: {}: reconnect_after_s without disconnect_at_s", where(origin, map), path.empty() ? "defaults" : path);
}

}  // namespace

LinkSpec Profile::for_node(uint32_t index, const std::string& name) const {
  for (const Entry& e : nodes)
    if ((e.name && *e.name == name) || (e.index && *e.index == index)) return e.spec;
  return defaults;
}

double Profile::max_speed() const {
  double m = defaults.speed;
  for (const Entry& e : nodes) m = std::max(m, e.spec.speed);
  return m;
}

double Profile::slowdown(const LinkSpec& spec) const { return max_speed() / spec.speed; }

Profile parse_profile(const std::string& text, const std::string& origin) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    fail("{}:{}: not valid YAML: {}", origin, e.mark.line + 1, e.msg);
  }
  if (!root.IsMap()) fail("{}: a profile is a map with 'defaults' and 'nodes' (see deploy/profiles/)", origin);
  Profile p;
  for (const auto& kv : root) {
    std::string key = kv.first.as<std::string>();
    if (key != "profile" && key != "defaults" && key != "nodes")
      fail("{}: unknown key '{}' (known: profile, defaults, nodes)", where(origin, kv.first), key);
  }
  if (root["profile"]) p.name = root["profile"].as<std::string>();
  if (root["defaults"]) apply(origin, "defaults", root["defaults"], p.defaults, {});
  if (const YAML::Node nodes = root["nodes"]) {
    if (!nodes.IsSequence()) fail("{}: nodes: expected a list of entries", where(origin, nodes));
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      const YAML::Node& n = nodes[i];
      std::string path = fmt::format("nodes[{}]", i);
      Profile::Entry e;
      e.spec = p.defaults;
      apply(origin, path, n, e.spec, {"name", "index"});
      if (n["name"]) {
        if (!n["name"].IsScalar() || n["name"].Scalar().empty()) fail("{}: {}.name: expected a node name", where(origin, n["name"]), path);
        e.name = n["name"].Scalar();
      }
      if (n["index"]) e.index = static_cast<uint32_t>(number(origin, path + ".index", n["index"], 0, 1 << 20));
      if (e.index && n["index"].as<double>() != *e.index)
        fail("{}: {}.index: expected a whole number", where(origin, n["index"]), path);
      if (!e.name && !e.index) fail("{}: {}: an entry needs a name or an index", where(origin, n), path);
      p.nodes.push_back(std::move(e));
    }
  }
  return p;
}

Profile load_profile(const std::string& path) {
  return parse_profile(read_file_whole(path, "profile", std::size_t{1} << 20), path);
}

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
