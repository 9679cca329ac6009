// sirad: the worker node (proto/PROTOCOL.md): connects a DEALER to a coordinator, says HELLO,
// receives the run and the scene (unless it holds it: node/scene_cache.h), meshes it and checks
// its hash, then runs the bundles it is
// granted on its OpenCL device and exchanges chunk states as the grants say, until STOP; then
// it waits for the next run. The bundle engine and the solver know nothing of the network.
#pragma once
#include <atomic>
#include <optional>
#include <string>

#include <zmq.hpp>

#include "engine/bundle_cl.h"
#include "proto/security.h"

namespace sirad::node {

struct NodeOptions {
  std::string name = "node";
  std::string device;                      // see select_device
  std::optional<TransferPath> transfer;    // the bundle engine's path (engine/bundle_cl.h; default: the device's)
  const std::atomic<bool>* stop = nullptr; // set: leave after the current message
  int poll_ms = 100;
  // Reconnecting to a coordinator that went away: ZeroMQ retries after reconnect_ms, doubling up
  // to reconnect_max_ms; HELLO without a run backs off the same way until a coordinator answers.
  int reconnect_ms = 1000, reconnect_max_ms = 32000;
  // The largest run this node takes (patches; a WELCOME beyond it is refused before any
  // meshing), and so the largest frame it accepts (ZMQ_MAXMSGSIZE, said in HELLO: a chunk of
  // that many patches, 96 MiB at the default 4 M).
  uint32_t max_patches = uint32_t{1} << 22;
  // CURVE (proto/security.h): the node's key pair and the coordinator's public key. Empty
  // server_key: none (inproc, or a TCP cluster run with --insecure).
  proto::KeyPair curve_keys;
  std::string server_key;
  // A folder that keeps the scenes this node was sent, named by their hash, across restarts
  // (node/scene_cache.h); empty: in memory only, for the process's life.
  std::string scene_cache;
  // Threads that render this node's tiles of a final gather (0: every core). Nodes that share
  // a machine (sirad render --nodes N) split its cores.
  int gather_threads = 0;
};

// Serves runs until `stop` is set or the coordinator sends BYE. Throws sirad::Error on a local
// failure (no device); protocol errors from the coordinator are logged and answered.
void serve(zmq::context_t& context, const std::string& endpoint, const NodeOptions& options);

}  // namespace sirad::node
