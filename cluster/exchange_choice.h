// sirad: --exchange-every auto on a real machine: the policy's choice (auto_exchange, policy.h)
// with the scene's model parameters fitted on an engine when the rule needs them. The one
// piece of the cluster's decisions that runs bundles, kept out of the policy.
#pragma once
#include <vector>

#include "cluster/policy.h"
#include "cluster/settings.h"
#include "engine/bundle.h"
#include "model/model.h"
#include "scene/mesh.h"

namespace sirad::cluster {

// The scene's contraction and sigma_1 / C for auto_exchange: model::fit_scene with a small
// budget (32 chains x 4 bounces, 16 first bounces) on `engine`.
model::Scene quick_scene_fit(const PatchMesh& mesh, BundleEngine& engine, uint64_t seed);

// --exchange-every auto for a run of `s`: auto_exchange with the scene fitted on `engine` (or,
// without one, this machine's OpenCL device, else the plain C++ reference engine) when the
// model needs it (the average rule; a fit that fails falls back to the chain rule's choice and
// says so).
// `coordinator_transfer`: coordinator_seconds of the coordinator's own link (0: not a
// bottleneck; see auto_exchange).
ExchangeSetting auto_setting(const RunSettings& s, const PatchMesh& mesh, const std::vector<NodeCost>& nodes,
                             uint32_t chunks, BundleEngine* engine = nullptr, double coordinator_transfer = 0);

}  // namespace sirad::cluster
