// sirad tests: a coordinator and node threads over real ZeroMQ sockets, in one process.
#pragma once
#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "cli/embedded.h"
#include "cluster/status.h"
#include "scene/scene.h"

namespace sirad::cluster::test {

struct Outcome {
  RunResult result;
  PatchMesh mesh;
};

// Runs `config` with `nodes` node threads named n0, n1, ... connected to a ROUTER bound at
// `endpoint`; the run waits for `min_nodes` of them (0: all) and fails only when hung (900 s,
// tests/process_util.h kHangS).
inline Outcome run_cluster(RunConfig config, int nodes, const std::string& endpoint, uint32_t min_nodes = 0) {
  Outcome out;
  out.mesh = mesh_scene(config.scene, config.mesh_options);
  config.min_nodes = min_nodes > 0 ? min_nodes : static_cast<uint32_t>(nodes);
  if (config.timeout_s == 0) config.timeout_s = 900;
  out.result = embedded::run(config, out.mesh, {.nodes = nodes, .endpoint = endpoint, .name_prefix = "n"}).result;
  return out;
}

// The built-in furnace (every patch's exact radiosity is 2) at about 300 patches.
inline RunConfig furnace(uint64_t bundles) {
  RunConfig c;
  c.scene = builtin_furnace();
  c.mesh_options.target_patches = 300;
  c.bundles = bundles;
  c.seed = 3;
  return c;
}

inline const NodeReport& node_named(const RunResult& r, const std::string& name) {
  for (const auto& n : r.nodes)
    if (n.name == name && !n.dead) return n;
  for (const auto& n : r.nodes)
    if (n.name == name) return n;
  throw std::runtime_error(fmt::format("no node {}", name));
}

}  // namespace sirad::cluster::test
