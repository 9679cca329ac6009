// sirad: the run status as JSON.
#include "coordinator/status.h"

#include <fmt/format.h>

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
                         "\"last_seen_s\": {:.3f}, \"bundles_per_s\": {:.3f}, \"busy_s\": {:.3f}, \"idle_s\": {:.3f}}}",
                         nodes.empty() ? "" : ", ", json_string(n.name), json_string(n.device), json_string(n.state),
                         n.bundles, n.exchanges, n.last_seen_s, n.rate, n.busy_s, n.idle_s);
  double rate = s.elapsed_s > 0 ? static_cast<double>(s.bundles_done) / s.elapsed_s : 0.0;
  std::string error = s.error_estimate < 0 ? "null" : fmt::format("{:.6g}", s.error_estimate);
  return fmt::format("{{\"bundles_done\": {}, \"bundles\": {}, \"elapsed_s\": {:.3f}, \"bundles_per_s\": {:.3f}, "
                     "\"error_estimate\": {}, \"exchanges\": {}, \"bytes_in\": {}, \"bytes_out\": {}, "
                     "\"nodes\": [{}]}}\n",
                     s.bundles_done, s.bundles, s.elapsed_s, rate, error, s.exchanges, s.bytes_in, s.bytes_out, nodes);
}

void write_status(const std::string& path, const Status& status) {
  std::string text = to_json(status);
  AtomicFile f(path);
  f.write(text.data(), text.size());
  f.commit();
}

}  // namespace sirad::cluster
