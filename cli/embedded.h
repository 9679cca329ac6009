// sirad: the embedded cluster driver: the coordinator on the calling thread and N worker nodes
// on threads of this process, over a real ZeroMQ socket (inproc by default) with the same code
// as a cluster of processes. `sirad render --nodes N`, the benches and the tests all run it.
#pragma once
#include <functional>
#include <optional>
#include <string>

#include "cluster/result.h"
#include "cluster/settings.h"
#include "engine/bundle_cl.h"
#include "scene/mesh.h"

namespace sirad::embedded {

struct Options {
  int nodes = 1;
  std::string endpoint = "inproc://sirad-embedded";  // or tcp://127.0.0.1:* (a port the system picks)
  std::string name_prefix = "local-";                // nodes are named PREFIX0, PREFIX1, ...
  std::string device;                                // each node's OpenCL device (select_device)
  std::optional<TransferPath> transfer;              // their bundle engines' path (default: the device's)
  int poll_ms = 100;                                 // the nodes' NodeOptions::poll_ms
  // Threads each node renders a final gather's tiles on (NodeOptions::gather_threads); 0: the
  // machine's cores split among the nodes, so that N nodes on one machine do not start N times
  // as many threads as it has cores.
  int gather_threads = 0;
  // Called once the run is over and the nodes are told to leave, before they are joined (the
  // outputs are written while they go).
  std::function<void(const cluster::RunResult&)> on_done;
};

struct Outcome {
  cluster::RunResult result;
  double coordinate_s = 0;  // until coordinate() returned
  double total_s = 0;       // until every node thread was joined
};

// Runs `config` on `mesh` (meshed from config.scene with config.mesh_options). The run is
// strict (a node's ERROR ends it) and fails at once when a node thread fails, with that node's
// error. Throws what coordinate() throws otherwise.
Outcome run(cluster::RunConfig config, const PatchMesh& mesh, const Options& options);

}  // namespace sirad::embedded
