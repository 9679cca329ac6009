// sirad: network-emulation profiles (YAML) and the link model.
#include "cluster/profile.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "util/atomic_file.h"
#include "util/error.h"
#include "util/json_bounded.h"

namespace sirad::emulation {

namespace {

// A profile describes at most the most nodes a run can have (--min-nodes 1..4096).
constexpr std::size_t kMaxProfileEntries = 4096;

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

// A map's key as a name: a plain scalar, or one error with its line (yaml-cpp's own answer to
// a list or map as a key is "bad conversion", without one).
std::string key_of(const std::string& origin, const YAML::Node& key) {
  if (!key.IsScalar()) fail("{}: a key is a plain name, not a list or a map", where(origin, key));
  return key.Scalar();
}

// The link keys of `map` over `spec`; anything else in the map is an error unless in `extra`.
void apply(const std::string& origin, const std::string& path, const YAML::Node& map, LinkSpec& spec,
           const std::vector<std::string>& extra) {
  if (!map.IsMap()) fail("{}: {}: expected a map of settings", where(origin, map), path);
  for (const auto& kv : map) {
    std::string key = key_of(origin, kv.first);
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
  // Nesting is bounded before yaml-cpp builds the tree (no profile needs more than 4 levels; a
  // flow list nested thousands deep is "bad file" to yaml-cpp).
  if (json_depth(text, kMaxJsonDepth) > kMaxJsonDepth) fail("{}: lists or maps nested deeper than {} levels", origin, kMaxJsonDepth);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    fail("{}:{}: not valid YAML: {}", origin, e.mark.line + 1, e.msg);
  }
  Profile p;
  try {
    if (!root.IsMap()) fail("{}: a profile is a map with 'defaults' and 'nodes' (see deploy/profiles/)", origin);
    for (const auto& kv : root) {
      std::string key = key_of(origin, kv.first);
      if (key != "profile" && key != "defaults" && key != "nodes" && key != "coordinator")
        fail("{}: unknown key '{}' (known: profile, defaults, nodes, coordinator)", where(origin, kv.first), key);
    }
    if (root["profile"]) {
      if (!root["profile"].IsScalar()) fail("{}: profile: expected a name", where(origin, root["profile"]));
      p.name = root["profile"].Scalar();
    }
    if (root["defaults"]) apply(origin, "defaults", root["defaults"], p.defaults, {});
    if (const YAML::Node c = root["coordinator"]) {
      if (c.IsMap())
        for (const auto& kv : c) {
          std::string key = key_of(origin, kv.first);
          if (key == "speed" || key == "disconnect_at_s" || key == "reconnect_after_s")
            fail("{}: coordinator.{}: not a setting of the coordinator's link (known: latency_ms, jitter_ms, bandwidth_mbit, "
                 "up_mbit, down_mbit, loss)",
                 where(origin, kv.first), key);
        }
      LinkSpec spec;
      apply(origin, "coordinator", c, spec, {});
      p.coordinator = spec;
    }
    if (const YAML::Node nodes = root["nodes"]) {
      if (!nodes.IsSequence()) fail("{}: nodes: expected a list of entries", where(origin, nodes));
      if (nodes.size() > kMaxProfileEntries)
        fail("{}: nodes: {} entries (at most {}, the most nodes a run has)", where(origin, nodes), nodes.size(), kMaxProfileEntries);
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
  } catch (const YAML::Exception& e) {  // a key or value of the wrong kind (a map for a name, ...)
    fail("{}:{}: {}", origin, e.mark.line + 1, e.msg);
  }
  return p;
}

Profile load_profile(const std::string& path) {
  return parse_profile(read_file_whole(path, "profile", std::size_t{1} << 20), path);
}

}  // namespace sirad::emulation
