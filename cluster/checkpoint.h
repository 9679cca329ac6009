// sirad: the coordinator's checkpoint: everything a run has accepted, so a
// coordinator that stops (SIGTERM, a crash, a reboot) can be resumed with `--resume FILE`:
// the run's settings and scene hash, every node's last state per chunk (sums and counts), its
// counters and the ledger's record of the bundles it ran, and the run's counters. The file is a
// protobuf message (wire::Checkpoint in proto/sirad.proto) behind a header with its format
// version and XXH3-64 checksum (PROTOCOL.md section 10), replaced atomically.
#pragma once
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "cluster/policy.h"
#include "cluster/settings.h"
#include "proto/codec.h"

namespace sirad::cluster {

inline constexpr const char* kCheckpointMagic = "sirad checkpoint";
inline constexpr uint32_t kCheckpointVersion = 2;

// Writes `c` to `path` atomically (a temporary renamed over it): a crash mid-write leaves the
// previous checkpoint whole.
void write_checkpoint(const std::string& path, const wire::Checkpoint& c);

// Reads a checkpoint (a regular file of at most 16 GiB) and checks it whole: magic, version
// and checksum (any damaged byte is refused), then every field within what a run can have
// (the settings as check() and from_wire take them, counts within the node's bundles and the
// budget, ranges within the budget and disjoint, times finite and within kMaxSeconds, sums
// finite and within their counts, texts and keys within their sizes); anything else is one
// error naming the file and what is wrong.
wire::Checkpoint read_checkpoint(const std::string& path);
// The same for a file's bytes (`label` names it in errors), and the file's bytes of a
// serialised wire::Checkpoint (the header before it: the fuzz target frames its inputs so).
wire::Checkpoint decode_checkpoint(std::string_view bytes, const std::string& label);
std::string frame_checkpoint(std::string_view payload);

// What the coordinator keeps of a run besides the policy's state: per node (by index) its name,
// CURVE key and times; the run's counters; the keys it quarantined.
struct CoordinatorRecord {
  struct Node {
    std::string name, key;
    double busy_s = 0, idle_s = 0;
  };
  std::vector<Node> nodes;
  double elapsed_s = 0;
  uint64_t crossings = 0, bytes_in = 0, bytes_out = 0, final_bytes = 0;
  std::set<std::string> quarantined_keys;
};

// The checkpoint of a run: its settings and wire Run, the policy's state, the coordinator's record.
wire::Checkpoint make_checkpoint(const RunSettings& s, const wire::Run& run, const PolicySnapshot& snapshot,
                                 const CoordinatorRecord& record);

// Continues checkpoint `c` in the run `run` (the same scene hash and chunk starts, else
// sirad::Error): `policy` restored and `run` given the exchange setting in force; returns the
// coordinator's record.
CoordinatorRecord resume_from(const wire::Checkpoint& c, wire::Run& run, Policy& policy);

// The policy's part of a checkpoint, both ways (names, times and keys are the coordinator's).
void put_snapshot(wire::Checkpoint& c, const PolicySnapshot& s);
PolicySnapshot snapshot_of(const wire::Checkpoint& c);

}  // namespace sirad::cluster
