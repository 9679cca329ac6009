// sirad: the coordinator (proto/PROTOCOL.md): serves one run on a ROUTER socket, handing out
// grants from the bundle budget, answering reports with the exchange the policy says, and
// collecting the final states into the count-weighted estimate. The bookkeeping is
// cluster/exchange.h; this file only moves messages.
#pragma once
#include <zmq.hpp>

#include "cluster/result.h"
#include "cluster/settings.h"
#include "cluster/status.h"
#include "proto/peer_bytes.h"
#include "scene/mesh.h"

namespace sirad::cluster {

// Serves one run of `mesh` (meshed from config.scene with config.mesh_options) until every
// bundle is done and every node's final state is in (or continues config.resume; its scene hash
// and chunks must match `mesh`). Malformed or unexpected messages are
// refused and logged; the run goes on. A node silent for `liveness` heartbeat intervals is
// declared dead: its outstanding grant returns to the budget and its last accepted state stays
// in the estimate. Throws sirad::Error on the timeout, and when `interrupt` is set (after the
// checkpoint, if any, is written).
// `peer_bytes`, if given, watches `router`'s connections and is told of each message read.
RunResult coordinate(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh, proto::PeerBytes* peer_bytes = nullptr);
// Throws sirad::Error for settings only the virtual-time cluster models (a profile's
// coordinator link); coordinate() checks it first.
void check_real_run(const RunConfig& config);

}  // namespace sirad::cluster
