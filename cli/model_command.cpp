// sirad: `sirad model`, the paper's cost and error model for one setup or a sweep (see commands.h).
#include <algorithm>
#include <cstdio>

#include <fmt/format.h>

#include "cli/commands.h"
#include "cluster/policy.h"
#include "cluster/profile.h"
#include "cluster/status.h"
#include "engine/bundle_cl.h"
#include "model/model_fit.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad::cli {
namespace {

// The setup and costs of a real run from its status file: P = the nodes that ran bundles, its
// I and S, T = its elapsed time (unless --time), T_i = busy time / bundles over the nodes, and
// T_e = the nodes' idle time (waiting for the next grant: in sync mode the exchange barrier)
// over exchanges x P x S, as equation (1) charges P S T_e per exchange. Without idle time
// (async mode, or exchanges only at the end) T_e stays the flag's.
void apply_run(ModelArgs& m) {
  cluster::Status st = cluster::read_status(m.from_run);
  uint32_t processors = 0;
  uint64_t bundles = 0, exchanges = 0;
  double busy = 0, idle = 0;
  for (const auto& n : st.nodes) {
    if (n.bundles == 0) continue;
    ++processors;
    bundles += n.bundles;
    exchanges += n.exchanges;
    busy += n.busy_s;
    idle += n.idle_s;
  }
  if (processors == 0 || !(busy > 0)) fail("{}: no node of the run reported bundles and busy time", m.from_run);
  m.setup.processors = processors;
  m.setup.exchange_every = st.exchange_every;
  m.setup.fraction = st.exchange_fraction;
  if (!m.time_given) m.time = st.elapsed_s;
  m.costs.t_iteration = busy / static_cast<double>(bundles);
  const bool measured = exchanges > 0 && idle > 0;
  if (measured) m.costs.t_exchange = idle / (static_cast<double>(exchanges) * processors * st.exchange_fraction);
  std::printf("# from the run %s: P = %u, I = %llu, S = %g (%s, %s), T = %.3f s, T_i = %.6f s (busy / bundles), "
              "T_e = %.6f s (%s)\n",
              m.from_run.c_str(), processors, static_cast<unsigned long long>(st.exchange_every), st.exchange_fraction,
              st.mode.c_str(), st.topology.c_str(), m.time, m.costs.t_iteration, m.costs.t_exchange,
              measured ? "idle / (exchanges x P x S)" : "no exchange waits in the run: --t-exchange");
}

// T_e of a sync exchange on the profile's links, as --exchange-every auto charges it
// (cluster/policy.h auto_exchange): P S T_e = max(S e, P S c), e the slowest of the P nodes'
// links (state up and back down), c the coordinator's link per node's state. A star and a ring
// both pass every state through the coordinator (PROTOCOL.md section 3.3): the same cost.
void apply_profile(ModelArgs& m, std::size_t patches) {
  emulation::Profile profile = emulation::load_profile(m.profile);
  double e = 0;
  for (uint32_t n = 0; n < m.setup.processors; ++n) {
    emulation::LinkSpec spec = profile.for_node(n, fmt::format("node-{}", n));
    e = std::max(e, cluster::exchange_seconds(patches, &spec));
  }
  const double c = profile.coordinator ? cluster::coordinator_seconds(patches, *profile.coordinator) : 0.0;
  m.costs.t_exchange = std::max(e / m.setup.processors, c);
  std::printf("# T_e from %s for %zu patches: the nodes' links %.6f s each (side by side), the coordinator's %s; "
              "T_e = %.6f s\n",
              m.profile.c_str(), patches, e, profile.coordinator ? fmt::format("{:.6f} s per node (in turn)", c).c_str() : "not modelled",
              m.costs.t_exchange);
}

}  // namespace

int model_table(ModelArgs m) {
  if (!m.profile.empty()) {
    if (!m.from_run.empty()) fail("--profile: --from-run measured T_e already; give one of them");
    if (m.t_exchange_flag->count() > 0) fail("--profile: it sets T_e; --t-exchange would be ignored");
    if (!m.state_patches && m.scene.empty()) fail("--profile needs the state's size: --state-patches N or --scene");
    if (m.sweep == "processors") fail("--profile: T_e depends on P, so it cannot sweep the processors");
  } else if (m.state_patches) {
    fail("--state-patches: only with --profile");
  }
  if (!m.from_run.empty()) apply_run(m);
  if (!m.scene.empty()) {
    PatchMesh mesh = mesh_scene(load_scene(m.scene), mesh_options_from(m.mesh, m.given));
    auto engine = make_cl_engine(mesh, {.device = m.device});
    model::SceneFit fit = model::fit_scene(mesh, *engine);
    m.scene_params.contraction = std::min(fit.contraction, 0.999);
    m.scene_params.sigma_ratio = fit.sigma_ratio;
    if (m.from_run.empty()) m.costs.t_iteration = fit.t_iteration;  // a run's own T_i is the better one
    std::printf("# fitted on %s (%zu patches, %llu bundles on %s): contraction a = %.4f +- %.4f, sigma_1 / C = %.4f, "
                "T_i = %.6f s\n",
                m.scene.c_str(), mesh.size(), static_cast<unsigned long long>(fit.bundles), engine->description().c_str(),
                fit.contraction, fit.contraction_se, fit.sigma_ratio, fit.t_iteration);
    if (!m.profile.empty() && !m.state_patches) apply_profile(m, mesh.size());
  }
  if (!m.profile.empty() && m.state_patches) apply_profile(m, static_cast<std::size_t>(*m.state_patches));
  model::check(m.setup);
  model::check(m.costs);
  model::check(m.scene_params);
  std::printf("processors,exchange_every,fraction,contraction,sigma_ratio,t_iteration,t_exchange,time,iterations,phases,"
              "relative_error,log_effective_samples,bias,sd%s\n", m.time_to > 0 ? ",time_to_error" : "");
  auto row = [&](const model::Setup& s) {
    model::Prediction p = model::predict(m.time, s, m.costs, m.scene_params);
    std::printf("%u,%llu,%g,%g,%g,%g,%g,%g,%llu,%llu,%.6g,%.6f,%.6g,%.6g", s.processors, static_cast<unsigned long long>(s.exchange_every),
                s.fraction, m.scene_params.contraction, m.scene_params.sigma_ratio, m.costs.t_iteration, m.costs.t_exchange, m.time,
                static_cast<unsigned long long>(p.iterations), static_cast<unsigned long long>(p.phases), p.relative_error,
                p.log_effective, p.bias, p.sd);
    if (m.time_to > 0) std::printf(",%.6g", model::time_to_error(m.time_to, s, m.costs, m.scene_params));
    std::printf("\n");
  };
  for (uint64_t k = 1; k <= (m.sweep == "none" ? 1 : m.max); ++k) {
    model::Setup s = m.setup;
    if (m.sweep == "processors") s.processors = static_cast<uint32_t>(k);
    if (m.sweep == "period") s.exchange_every = k;
    if (m.sweep == "fraction") s.fraction = static_cast<double>(k) / static_cast<double>(m.max);
    row(s);
  }
  model::Setup s = m.setup;
  std::printf("# best exchange period for the effective sample number (I = 1..%llu): %llu\n",
              static_cast<unsigned long long>(m.max),
              static_cast<unsigned long long>(model::best_period(m.time, s, m.costs, m.scene_params.contraction, m.max)));
  return 0;
}

}  // namespace sirad::cli
