// sirad: the run status as JSON.
#include "cluster/status.h"

#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "util/atomic_file.h"
#include "util/error.h"
#include "util/json_bounded.h"

namespace sirad::cluster {

using Json = nlohmann::ordered_json;

std::string to_json(const Status& s) {
  Json nodes = Json::array();
  for (const auto& n : s.nodes) {
    Json o = {{"name", n.name},         {"device", n.device},       {"state", n.state},         {"bundles", n.bundles},
              {"exchanges", n.exchanges}, {"last_seen_s", n.last_seen_s}, {"bundles_per_s", n.rate}, {"busy_s", n.busy_s},
              {"idle_s", n.idle_s},     {"bytes_in", n.bytes_in},   {"bytes_out", n.bytes_out}, {"suspicion", n.suspicion}};
    if (!n.why.empty()) o["why"] = n.why;
    if (n.tiles > 0) o["tiles"] = n.tiles;
    nodes.push_back(std::move(o));
  }
  const double rate = s.elapsed_s > 0 ? static_cast<double>(s.bundles_done) / s.elapsed_s : 0.0;
  auto or_null = [](bool given, const auto& v) { return given ? Json(v) : Json(nullptr); };
  Json j = {{"bundles_done", s.bundles_done},
                  {"bundles", s.bundles},
                  {"patches", s.patches},
                  {"elapsed_s", s.elapsed_s},
                  {"bundles_per_s", rate},
                  {"patch_bundles_per_s", rate * static_cast<double>(s.patches)},
                  {"error_estimate", or_null(s.error_estimate >= 0, s.error_estimate)},
                  {"exchanges", s.exchanges},
                  {"bytes_in", s.bytes_in},
                  {"bytes_out", s.bytes_out},
                  {"scenes_sent", s.scenes_sent},
                  {"scenes_from_cache", s.scenes_from_cache},
                  {"exchange_every", s.exchange_every},
                  {"exchange_fraction", s.exchange_fraction},
                  {"mode", s.mode},
                  {"topology", s.topology},
                  {"target_error", or_null(s.target_error > 0, s.target_error)},
                  {"ended_by", or_null(!s.ended_by.empty(), s.ended_by)},
                  {"settings", Json::object()},
                  {"nodes", std::move(nodes)}};
  for (const auto& [flag, text] : s.settings) j["settings"][flag] = text;
  if (s.image_tiles > 0) {
    j["image_tiles"] = s.image_tiles;
    j["image_tiles_done"] = s.image_tiles_done;
  }
  return j.dump(-1, ' ', false, Json::error_handler_t::replace) + "\n";
}

namespace {

// Field `key` of `node` as T, or one clear error naming the file and where. Optional fields
// (of a status file of an earlier version) are `fallback` where missing.
template <class T>
T field(const Json& node, const char* key, const std::string& path, const std::string& where, std::optional<T> fallback = {}) {
  auto it = node.find(key);
  if (it == node.end() || it->is_null()) {
    if (fallback) return *fallback;
    fail("{}: {}'{}' is missing", path, where, key);
  }
  try {
    return it->template get<T>();
  } catch (const Json::exception&) {
    fail("{}: {}'{}' is not a valid value ({})", path, where, key, it->dump().substr(0, 40));
  }
}

// The largest status file read back: a run of 4096 nodes is about 1.2 MB.
constexpr std::size_t kMaxStatusBytes = std::size_t{1} << 26;
constexpr std::size_t kMaxStatusSettings = 256;  // far beyond the table's rows

}  // namespace

Status read_status(const std::string& path) {
  Json root;
  const std::string text = read_file_whole(path, "status file", kMaxStatusBytes);
  check_json_depth(text, path);
  try {
    root = Json::parse(text);
  } catch (const Json::parse_error& e) {
    fail("{}: not a status file ({})", path, e.what());
  }
  if (!root.is_object()) fail("{}: not a status file (expected a JSON object)", path);
  Status s;
  s.bundles_done = field<uint64_t>(root, "bundles_done", path, "");
  s.bundles = field<uint64_t>(root, "bundles", path, "");
  s.elapsed_s = field<double>(root, "elapsed_s", path, "");
  s.exchanges = field<uint32_t>(root, "exchanges", path, "");
  s.exchange_every = field<uint64_t>(root, "exchange_every", path, "");
  s.exchange_fraction = field<double>(root, "exchange_fraction", path, "");
  s.mode = field<std::string>(root, "mode", path, "");
  s.topology = field<std::string>(root, "topology", path, "");
  // Fields a status file of an earlier version does not have: 0 where missing.
  s.patches = field<uint64_t>(root, "patches", path, "", 0);
  s.scenes_sent = field<uint32_t>(root, "scenes_sent", path, "", 0);
  s.scenes_from_cache = field<uint32_t>(root, "scenes_from_cache", path, "", 0);
  s.ended_by = field<std::string>(root, "ended_by", path, "", "");
  s.error_estimate = field<double>(root, "error_estimate", path, "", -1.0);
  s.target_error = field<double>(root, "target_error", path, "", 0.0);
  s.bytes_in = field<uint64_t>(root, "bytes_in", path, "", 0);
  s.bytes_out = field<uint64_t>(root, "bytes_out", path, "", 0);
  s.image_tiles = field<uint64_t>(root, "image_tiles", path, "", 0);
  s.image_tiles_done = field<uint64_t>(root, "image_tiles_done", path, "", 0);
  if (s.image_tiles_done > s.image_tiles) fail("{}: 'image_tiles_done' is more than 'image_tiles'", path);
  if (auto settings = root.find("settings"); settings != root.end()) {  // absent in a status file of an earlier version
    if (!settings->is_object() || settings->size() > kMaxStatusSettings)
      fail("{}: 'settings' is not an object of at most {} settings", path, kMaxStatusSettings);
    for (const auto& [flag, text] : settings->items()) {
      if (!text.is_string()) fail("{}: setting '{}' is not a string", path, peer_text(flag, 40));
      s.settings.emplace_back(flag, text.get<std::string>());
    }
  }
  auto nodes = root.find("nodes");
  if (nodes == root.end() || !nodes->is_array()) fail("{}: 'nodes' is missing or not a list", path);
  for (std::size_t i = 0; i < nodes->size(); ++i) {
    const std::string where = fmt::format("node {}: ", i);
    const Json& node = (*nodes)[i];
    if (!node.is_object()) fail("{}: node {} is not an object", path, i);
    Status::Node n;
    n.name = field<std::string>(node, "name", path, where);
    n.state = field<std::string>(node, "state", path, where);
    n.bundles = field<uint64_t>(node, "bundles", path, where);
    n.exchanges = field<uint32_t>(node, "exchanges", path, where);
    n.busy_s = field<double>(node, "busy_s", path, where);
    n.idle_s = field<double>(node, "idle_s", path, where);
    n.device = field<std::string>(node, "device", path, where, "");
    n.why = field<std::string>(node, "why", path, where, "");
    n.suspicion = field<double>(node, "suspicion", path, where, 0.0);
    n.rate = field<double>(node, "bundles_per_s", path, where, 0.0);
    n.bytes_in = field<uint64_t>(node, "bytes_in", path, where, 0);
    n.bytes_out = field<uint64_t>(node, "bytes_out", path, where, 0);
    n.tiles = field<uint64_t>(node, "tiles", path, where, 0);
    if (!std::isfinite(n.busy_s) || n.busy_s < 0 || !std::isfinite(n.idle_s) || n.idle_s < 0)
      fail("{}: {}busy_s and idle_s must be finite and non-negative", path, where);
    s.nodes.push_back(n);
  }
  if (!std::isfinite(s.elapsed_s) || s.elapsed_s < 0) fail("{}: 'elapsed_s' must be finite and non-negative", path);
  if (!(s.exchange_fraction > 0 && s.exchange_fraction <= 1)) fail("{}: 'exchange_fraction' must be in (0, 1]", path);
  return s;
}

std::string peer_text(std::string_view s, std::size_t max) {
  std::string out(s.substr(0, max));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e) c = '?';
  return out;
}

void write_status(const std::string& path, const Status& status) {
  write_file_atomic(path, to_json(status), Durability::replace_only);
}

}  // namespace sirad::cluster
