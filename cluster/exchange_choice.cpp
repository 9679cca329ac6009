// sirad: --exchange-every auto with a scene fit (see exchange_choice.h).
#include "cluster/exchange_choice.h"

#include <algorithm>
#include <memory>

#include <fmt/format.h>

#include "engine/bundle_cl.h"
#include "model/model_fit.h"
#include "util/error.h"

namespace sirad::cluster {

model::Scene quick_scene_fit(const PatchMesh& mesh, BundleEngine& engine, uint64_t seed) {
  model::FitOptions o;
  o.seed = seed;
  o.chains = 32;
  o.bounces = 4;
  o.first_bounce = 16;
  model::SceneFit f = model::fit_scene(mesh, engine, o);
  return {std::clamp(f.contraction, 0.0, 0.99), std::max(f.sigma_ratio, 1e-6)};
}

ExchangeSetting auto_setting(const RunSettings& c, const PatchMesh& mesh, const std::vector<NodeCost>& nodes,
                             uint32_t chunks, BundleEngine* engine, double coordinator_transfer) {
  model::Scene scene;
  if (c.rule == UpdateRule::average) {
    try {
      std::unique_ptr<BundleEngine> own;
      if (engine == nullptr) {
        try {
          own = make_cl_engine(mesh, {});
        } catch (const std::exception&) {
          own = make_reference_engine(mesh);
        }
        engine = own.get();
      }
      scene = quick_scene_fit(mesh, *engine, c.seed);
    } catch (const Error& e) {
      ExchangeSetting s = auto_exchange(UpdateRule::chain, scene, nodes, c.mode, c.bundles, chunks, c.time_limit_s,
                                        coordinator_transfer);
      s.why = fmt::format("the scene fit failed ({}); {}", e.what(), s.why);
      return s;
    }
  }
  return auto_exchange(c.rule, scene, nodes, c.mode, c.bundles, chunks, c.time_limit_s, coordinator_transfer);
}

}  // namespace sirad::cluster
