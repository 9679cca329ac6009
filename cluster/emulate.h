// sirad: the virtual-time cluster (`sirad emulate`). P emulated nodes live in one
// process, each with its own Solver (its own chain, as on a real node) on one shared engine, so
// every bundle is a real bundle on the real kernels, run one at a time. Nothing waits: a
// discrete-event loop advances a virtual clock by each grant's cost (its bundles x the bundle
// time x the node's slowdown from the profile) and by each message's delivery through the
// profile's link model (emulation::LinkModel, the one the real coordinator and nodes shape
// their messages with). Every decision, grants, the sync barrier, exchanges, closing, is made
// by the same Policy (cluster/policy.h) as a real run. For a given seed and bundle time the
// run is deterministic: the same timeline and the same result, bit for bit.
//
// What is modelled: per node, setup (the scene's transfer on the downlink, then the burn-in
// bundles), grants run back to back, a node's messages handled in arrival order between grants
// (as node/node.cpp does), the coordinator's own link when the profile gives one (shared by every
// node's messages), REPORT / UPDATE / FINAL sizes of 24 bytes per patch of each chunk
// plus a 64-byte header (proto/PROTOCOL.md), the coordinator answering at once. With a final
// gather (RunConfig::final_gather) the image follows as on a real cluster: the same ImagePhase
// (cluster/image_phase.h) grants the tiles, each node renders them for real, one grant at a
// time, and a tile costs the tile time x the node's slowdown x its share of a whole tile's
// pixels; IMAGE carries the solution (24 bytes a patch), PIXELS 36 bytes a pixel. Not
// modelled: the coordinator's own processing time, heartbeats, the coordinator's spot checks,
// and disconnects (a profile with disconnect_at_s is refused: liveness belongs to real runs).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "cluster/result.h"
#include "cluster/settings.h"
#include "engine/bundle.h"
#include "engine/shot.h"
#include "render/gather.h"
#include "solver/solver.h"

namespace sirad::cluster {

struct EmulateConfig {
  RunConfig run;           // the run's settings and profile, as for coordinate() (min_nodes:
                           // nodes ready before the first grant, as there; the clocks'
                           // settings: virtual seconds)
  uint32_t nodes = 0;      // P emulated nodes, named emu-0, emu-1, ...
  double bundle_s = 0;     // seconds of one bundle (a solver step) at slowdown 1; 0: measure
                           // it (measure_bundle_seconds) before the run
  double tile_s = 0;       // with a final gather: seconds of one whole tile at slowdown 1; 0:
                           // measure it (measure_tile_seconds) once the solution is in
};

// One event of the virtual timeline (for --timeline and the determinism test).
struct TimelineEvent {
  double t = 0;            // virtual seconds since the start
  uint32_t node = 0;
  std::string what;        // ready | grant | report | update | stop | final; the image's:
                           // image | tiles | pixels (bundles: the tiles of the grant)
  uint64_t bundles = 0;    // grant and report: bundles of the grant; update/final: chunks
  bool operator==(const TimelineEvent&) const = default;
};

struct EmulatedNode {
  std::string name;
  double speed = 1, slowdown = 1;  // the profile's speed factor and the resulting slowdown
  uint64_t bundles = 0;
  uint32_t exchanges = 0;
  double ready_s = 0;      // when its READY reached the coordinator
  double busy_s = 0;       // running bundles
  double idle_s = 0;       // waiting for work between its first grant and its STOP
  double end_s = 0;        // when its FINAL reached the coordinator
  double utilisation = 0;  // busy_s over the run's virtual wall time
  uint64_t tiles = 0;      // tiles of the image it rendered
};

struct EmulateResult {
  RunResult run;           // as a real run reports it (busy/idle in virtual seconds)
  double bundle_s = 0;     // the bundle time used
  double wall_s = 0;       // virtual wall time: until the last FINAL is in (the image's own
                           // virtual time is run.image_seconds)
  double tile_s = 0;       // the tile time used (0: no image)
  double real_s = 0;       // real seconds the emulation took
  double error_estimate = -1;  // the run's own estimate at the end (Policy::error_estimate)
  std::string exchange_why;    // --exchange-every auto: what it chose and why
  std::vector<EmulatedNode> nodes;
  std::vector<TimelineEvent> timeline;
};

// Throws sirad::Error for settings the emulation cannot model (no nodes; a disconnect) or hold
// (the nodes' solver state for `patches` would not fit in half of this machine's memory).
void check_emulation(const EmulateConfig& config, std::size_t patches);

// Median seconds of one solver step of `options` on these engines (steps timed after the
// solver's burn-in, which is not counted).
double measure_bundle_seconds(const PatchMesh& mesh, BundleEngine& engine, ShotEngine* shots,
                              const SolverOptions& options, int steps = 9);
// Median seconds of rendering one whole tile (ImagePhase::kTileSide a side, from the image's
// middle, cut at its edges) of `camera` with `gather`, over `renders` renders.
double measure_tile_seconds(const FinalGather& gather, const Camera& camera, int renders = 3);

// Runs the emulated cluster on `mesh` (meshed from config.run.scene). `shots` is needed when
// the run has a first shot. Throws sirad::Error for settings the emulation cannot model.
EmulateResult emulate(const EmulateConfig& config, const PatchMesh& mesh, BundleEngine& engine,
                      ShotEngine* shots);

// CSV of the per-node figures (name, speed, bundles, exchanges, busy, idle, utilisation, end)
// and of the timeline (t, node, event, bundles), with a header line each.
std::string nodes_csv(const EmulateResult& result);
std::string timeline_csv(const EmulateResult& result);

}  // namespace sirad::cluster
