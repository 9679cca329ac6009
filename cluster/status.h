// sirad: a snapshot of a cluster run, for the terminal view, --status-json and tools. Plain
// data: the coordinator fills it about once a second and at the end of the run.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace sirad::cluster {

struct Status {
  uint64_t bundles_done = 0, bundles = 0;
  uint64_t patches = 0;  // of the run's mesh (patch-bundles per second: bundles per second x patches)
  double elapsed_s = 0;
  // Relative RMS error of the estimate per patch (area-weighted, non-emitting patches) from the
  // spread of the nodes' independent estimates; negative while fewer than two nodes have sent
  // states (Aggregate::spread_error).
  double error_estimate = -1;
  uint32_t exchanges = 0;
  uint64_t bytes_in = 0, bytes_out = 0;  // exchange traffic so far (REPORT / UPDATE bulk)
  // Nodes the scene was sent to, and nodes that held it already (Hello.scene_hashes).
  uint32_t scenes_sent = 0, scenes_from_cache = 0;
  // The run's exchange settings (for `sirad model --from-run`): I (0: only at the end), S.
  uint64_t exchange_every = 0;
  double exchange_fraction = 1.0;
  std::string mode, topology;
  double target_error = 0;  // --target-error (0: none)
  // Every setting of the run as its flag's text, (flag, text) in the table's order (settings.h
  // settings_text): as started, so --exchange-every auto is "auto" here and its choice above.
  std::vector<std::pair<std::string, std::string>> settings;
  // How the run ended, in the last status of a run ("" while it runs): "budget", "time limit",
  // "target error (...)", "interrupted", or "bundle cap reached short of the target error".
  std::string ended_by;
  // The run's image by a final gather, once its tiles are out to the nodes (PROTOCOL.md
  // section 3.4): its tiles and those placed so far (0 and 0: no image, or not yet).
  uint64_t image_tiles = 0, image_tiles_done = 0;
  struct Node {
    std::string name;
    std::string device;        // as the node described it in HELLO
    std::string state;         // "joining" | "working" | "waiting" | "done" | "dead" | "quarantined"
    uint64_t bundles = 0;
    uint32_t exchanges = 0;
    double last_seen_s = 0;    // seconds since its last message
    double rate = 0;           // bundles per second since it was ready
    double busy_s = 0;         // its own time running bundles (as last reported)
    double idle_s = 0;         // its own time waiting for a grant while the run had work
    uint64_t bytes_in = 0, bytes_out = 0;  // its states taken in (REPORT, FINAL) and updates sent to it
    std::string why;           // quarantined: what it sent; dead: why it was declared dead
    // The largest plausibility score of the states taken from it (cluster/plausibility.h):
    // how near it came to a quarantine for implausible data, which is above 1.
    double suspicion = 0;
    uint64_t tiles = 0;        // tiles of the run's image it rendered
  };
  std::vector<Node> nodes;
};

// Text a peer sent (a node's name, its device, an ERROR's reason), for a log line or a terminal:
// at most `max` bytes, every byte outside printable ASCII (newlines, escape sequences, UTF-8)
// as '?', so no peer can forge a line or move the cursor.
std::string peer_text(std::string_view s, std::size_t max);

// The status as one line of JSON (nlohmann::json: names escaped, a peer's bytes outside UTF-8
// replaced), ending in a newline.
std::string to_json(const Status& status);
// Reads a --status-json file back (the run settings and every node's counters); throws
// sirad::Error naming the file and the field for anything missing or malformed.
Status read_status(const std::string& path);
// Rewrites `path` atomically with to_json(status) (for --status-json), without an fsync: it is
// rewritten 4 times a second on the run's loop thread (Durability::replace_only).
void write_status(const std::string& path, const Status& status);

}  // namespace sirad::cluster
