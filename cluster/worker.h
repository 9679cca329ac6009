// sirad: a node's part of one run, free of sockets and clocks: the solver of its chain on its
// engines, the run's chunk table, and what each message of the coordinator makes it do (a
// grant: run bundles, then report the chunks it names; an update: absorb the others' state; a
// stop: report every chunk). The ZeroMQ node (node/node.cpp) and the virtual-time cluster
// (cluster/emulate.cpp) both run this one class, so an emulated node does what a real one does.
// Everything the coordinator names (chunks, their sizes, its counts) is checked against the
// run's own table before it is used.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "cluster/exchange.h"
#include "cluster/policy.h"
#include "cluster/settings.h"
#include "engine/bundle.h"
#include "engine/shot.h"
#include "scene/mesh.h"
#include "solver/solver.h"

namespace sirad::cluster {

// A chunk's state as the wire and the policy carry it (3 doubles per patch, rgb) from
// per-patch values, and back (`flat.size()` must be a multiple of 3).
std::vector<double> flatten(std::span<const glm::dvec3> values);
std::vector<glm::dvec3> unflatten(std::span<const double> flat);

class Worker {
 public:
  // Chain `index` of a run of `settings` on `mesh`. `starts`: the first patch of each chunk
  // (as on the wire, without the end); throws sirad::Error unless they start at 0, increase
  // and stay within the mesh. Builds the solver, which runs the chain's burn-in; `cancelled`,
  // asked between its bundles, ends it with sirad::Error (SolverOptions::cancelled).
  Worker(const PatchMesh& mesh, BundleEngine& engine, ShotEngine* shots, const RunSettings& settings, uint32_t index,
         std::span<const uint32_t> starts, std::function<bool()> cancelled = {});

  // Runs the bundles of `ranges` in order; `between` is called after each and may stop the
  // grant (returns false: stopped, the report is not to be sent). True when every bundle ran.
  bool run(std::span<const Range> ranges, const std::function<bool()>& between = {});

  // This node's (sum, count) of each of `chunks`, for a REPORT or FINAL. Throws sirad::Error
  // for a chunk the run does not have (nothing is read out of bounds).
  std::vector<ChunkState> states(std::span<const uint32_t> chunks) const;
  std::vector<ChunkState> all_states() const;

  // The others' summed state of chunk `chunk` and their count, from an UPDATE: throws
  // sirad::Error for an unknown chunk or a sum of the wrong size (checked values: Solver::absorb).
  void absorb(uint32_t chunk, std::span<const double> sum, uint64_t count);

  // Its batch-means estimate once it can be trusted (Solver::error_estimate_ready), else 0:
  // what a REPORT carries.
  double reported_error() const;
  uint32_t chunks() const { return static_cast<uint32_t>(starts_.size() - 1); }
  const Solver& solver() const { return *solver_; }

 private:
  std::vector<uint32_t> starts_;  // with the end (the mesh's size) appended
  std::unique_ptr<Solver> solver_;
};

}  // namespace sirad::cluster
