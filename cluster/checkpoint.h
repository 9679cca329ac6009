// sirad: the coordinator's checkpoint: everything a run has accepted, so a
// coordinator that stops (SIGTERM, a crash, a reboot) can be resumed with `--resume FILE`:
// the run's settings and scene hash, every node's last state per chunk (sums and counts), its
// counters and the ledger's record of the bundles it ran, and the run's counters. The file is a
// protobuf message (wire::Checkpoint in proto/sirad.proto), replaced atomically.
#pragma once
#include <set>
#include <string>
#include <vector>

#include "cluster/policy.h"
#include "cluster/settings.h"
#include "proto/codec.h"

namespace sirad::cluster {

inline constexpr const char* kCheckpointMagic = "sirad checkpoint";
inline constexpr uint32_t kCheckpointVersion = 1;

// Writes `c` to `path` atomically (a temporary renamed over it): a crash mid-write leaves the
// previous checkpoint whole.
void write_checkpoint(const std::string& path, const wire::Checkpoint& c);

// Reads a checkpoint and checks it hangs together (magic, version, chunk boundaries, every
// node's counts and sums sized to the run, bundle ranges within the budget); anything else is
// one error naming the file and what is wrong.
wire::Checkpoint read_checkpoint(const std::string& path);

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
