// sirad: the run status as JSON.
#include "cluster/status.h"

#include <cmath>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "core/error.h"

#include "core/atomic_file.h"

namespace sirad::cluster {

namespace {

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (unsigned char c : s) {
    if (c == '"' || c == '\\') out += '\\', out += static_cast<char>(c);
    else if (c < 0x20) out += fmt::format("\\u{:04x}", c);
    else out += static_cast<char>(c);
  }
  return out + "\"";
}

}  // namespace

std::string to_json(const Status& s) {
  std::string nodes;
  for (const auto& n : s.nodes)
    nodes += fmt::format("{}{{\"name\": {}, \"device\": {}, \"state\": {}, \"bundles\": {}, \"exchanges\": {}, "
                         "\"last_seen_s\": {:.3f}, \"bundles_per_s\": {:.3f}, \"busy_s\": {:.3f}, \"idle_s\": {:.3f}, \"suspicion\": {:.3f}{}}}",
                         nodes.empty() ? "" : ", ", json_string(n.name), json_string(n.device), json_string(n.state),
                         n.bundles, n.exchanges, n.last_seen_s, n.rate, n.busy_s, n.idle_s, n.suspicion,
                         n.why.empty() ? "" : ", \"why\": " + json_string(n.why));
  double rate = s.elapsed_s > 0 ? static_cast<double>(s.bundles_done) / s.elapsed_s : 0.0;
  std::string error = s.error_estimate < 0 ? "null" : fmt::format("{:.6g}", s.error_estimate);
  return fmt::format("{{\"bundles_done\": {}, \"bundles\": {}, \"patches\": {}, \"elapsed_s\": {:.3f}, \"bundles_per_s\": {:.3f}, "
                     "\"patch_bundles_per_s\": {:.4g}, \"error_estimate\": {}, \"exchanges\": {}, \"bytes_in\": {}, \"bytes_out\": {}, "
                     "\"scenes_sent\": {}, \"scenes_from_cache\": {}, "
                     "\"exchange_every\": {}, \"exchange_fraction\": {}, \"mode\": {}, \"topology\": {}, "
                     "\"target_error\": {}, \"ended_by\": {}, \"nodes\": [{}]}}\n",
                     s.bundles_done, s.bundles, s.patches, s.elapsed_s, rate, rate * static_cast<double>(s.patches), error,
                     s.exchanges, s.bytes_in, s.bytes_out, s.scenes_sent, s.scenes_from_cache,
                     s.exchange_every, s.exchange_fraction, json_string(s.mode), json_string(s.topology),
                     s.target_error > 0 ? fmt::format("{:.6g}", s.target_error) : "null",
                     s.ended_by.empty() ? "null" : json_string(s.ended_by), nodes);
}

namespace {

// Field `key` of `node` as T, or one clear error naming the file and where.
template <class T>
T field(const YAML::Node& node, const char* key, const std::string& path, const std::string& where) {
  const YAML::Node v = node[key];
  if (!v || !v.IsScalar()) fail("{}: {}'{}' is missing", path, where, key);
  try {
    return v.as<T>();
  } catch (const YAML::Exception&) {
    fail("{}: {}'{}' is not a valid value ('{}')", path, where, key, v.Scalar());
  }
}

}  // namespace

Status read_status(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    fail("{}: cannot read the status file", path);
  } catch (const YAML::Exception& e) {
    fail("{}: not a status file (line {}: {})", path, e.mark.line + 1, e.msg);
  }
  if (!root.IsMap()) fail("{}: not a status file (expected a JSON object)", path);
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
  if (root["patches"]) s.patches = field<uint64_t>(root, "patches", path, "");
  if (root["scenes_sent"]) s.scenes_sent = field<uint32_t>(root, "scenes_sent", path, "");
  if (root["scenes_from_cache"]) s.scenes_from_cache = field<uint32_t>(root, "scenes_from_cache", path, "");
  if (root["ended_by"] && !root["ended_by"].IsNull()) s.ended_by = field<std::string>(root, "ended_by", path, "");
  const YAML::Node nodes = root["nodes"];
  if (!nodes || !nodes.IsSequence()) fail("{}: 'nodes' is missing or not a list", path);
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const std::string where = fmt::format("node {}: ", i);
    if (!nodes[i].IsMap()) fail("{}: node {} is not an object", path, i);
    Status::Node n;
    n.name = field<std::string>(nodes[i], "name", path, where);
    n.state = field<std::string>(nodes[i], "state", path, where);
    n.bundles = field<uint64_t>(nodes[i], "bundles", path, where);
    n.exchanges = field<uint32_t>(nodes[i], "exchanges", path, where);
    n.busy_s = field<double>(nodes[i], "busy_s", path, where);
    n.idle_s = field<double>(nodes[i], "idle_s", path, where);
    if (nodes[i]["why"]) n.why = field<std::string>(nodes[i], "why", path, where);
    if (nodes[i]["suspicion"]) n.suspicion = field<double>(nodes[i], "suspicion", path, where);
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
  write_file_atomic(path, to_json(status));
}

}  // namespace sirad::cluster
