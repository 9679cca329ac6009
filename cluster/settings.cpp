// sirad: a run's settings and their conversions (see settings.h).
#include "cluster/settings.h"

#include <algorithm>
#include <cmath>

#include "cluster/policy.h"
#include "engine/version.h"
#include "scene/encoding.h"
#include "solver/error_estimate.h"
#include "util/error.h"

namespace sirad::cluster {

void check(const RunSettings& s) {
  if (s.directions == Directions::stratified && s.rule != UpdateRule::chain)
    fail("stratified directions need the chain rule (under average they bias the estimate: engine/bundle.cpp)");
  check_first_shot(s.shots_per_bundle, s.shot_resolution);
  if (s.bundles == 0 || s.bundles > kMaxBundles) fail("bundles {} is outside 1..{}", s.bundles, kMaxBundles);
  if (s.grid != 0 && (s.grid < 2 || s.grid > kMaxGrid)) fail("grid {} is outside 2..{} (0: auto)", s.grid, kMaxGrid);
  if (s.burn_in < -1 || s.burn_in > kMaxBurnIn) fail("burn-in {} is outside 0..{} (-1: auto)", s.burn_in, kMaxBurnIn);
  if (!(s.fraction > 0 && s.fraction <= 1)) fail("exchange fraction {} is outside (0, 1]", s.fraction);
  if (s.chunks == 0 || s.chunks > proto::kMaxChunks) fail("chunks {} is outside 1..{}", s.chunks, proto::kMaxChunks);
  if (!(s.time_limit_s >= 0 && s.time_limit_s <= kMaxSeconds))
    fail("time limit {:.6g} s is outside 0..{:.0e} s", s.time_limit_s, kMaxSeconds);
  if (!(s.target_error >= 0 && s.target_error <= 1)) fail("target error {} is outside [0, 1]", s.target_error);
  if (s.mesh_options.target_patches > kMaxTargetPatches)
    fail("target patches {} is above {}", s.mesh_options.target_patches, kMaxTargetPatches);
  if (!(s.mesh_options.max_edge >= 0) || !std::isfinite(s.mesh_options.max_edge))
    fail("max edge {:.6g} is not a finite length >= 0", s.mesh_options.max_edge);
}

std::string target_error_problem(const RunSettings& s) {
  if (s.target_error > 0 && s.rule == UpdateRule::average && s.exchange_every == 0)
    return "--target-error under the average rule needs --exchange-every (its estimate is the spread of the nodes' "
           "exchanged states; the chain rule's needs no exchanges)";
  return "";
}

int run_grid(const RunSettings& s, const PatchMesh& mesh) { return s.grid == 0 ? auto_grid(mesh) : s.grid; }

wire::Run to_wire(const RunSettings& s, const PatchMesh& mesh, const std::vector<uint32_t>& chunk_starts) {
  wire::Run run;
  run.set_scene_hash(mesh.hash);
  run.set_seed(s.seed);
  run.set_grid(static_cast<uint32_t>(run_grid(s, mesh)));
  run.set_rule(to_string(s.rule));
  run.set_burn_in(s.burn_in);
  run.set_directions(to_string(s.directions));
  run.set_no_control_variate(!s.control_variate);
  run.set_shots_per_bundle(s.shots_per_bundle);
  run.set_shot_resolution(static_cast<uint32_t>(s.shot_resolution));
  for (std::size_t c = 0; c + 1 < chunk_starts.size(); ++c) run.add_chunk_starts(chunk_starts[c]);
  run.set_patches(static_cast<uint32_t>(mesh.size()));
  run.set_exchange_every(s.exchange_every);
  run.set_exchange_fraction(s.fraction);
  run.set_topology(s.topology == Topology::star ? "star" : "ring");
  run.set_mode(s.mode == Mode::sync ? "sync" : "async");
  run.set_bundles(s.bundles);
  run.set_target_patches(s.mesh_options.target_patches);
  run.set_max_edge(s.mesh_options.max_edge);
  return run;
}

RunSettings from_wire(const wire::Run& r) {
  const uint32_t chunks = static_cast<uint32_t>(r.chunk_starts_size());
  if (r.patches() == 0) fail("the run has no patches");
  if (chunks == 0 || chunks > proto::kMaxChunks || r.chunk_starts(0) != 0)
    fail("the run's {} chunks are not 1..{} starting at patch 0", chunks, proto::kMaxChunks);
  for (uint32_t i = 1; i < chunks; ++i)
    if (r.chunk_starts(static_cast<int>(i)) <= r.chunk_starts(static_cast<int>(i) - 1) ||
        r.chunk_starts(static_cast<int>(i)) >= r.patches())
      fail("chunk {} starts at patch {}: out of order (it must be after chunk {}'s and below the {} patches)", i,
           r.chunk_starts(static_cast<int>(i)), i - 1, r.patches());
  const std::string& source = r.scene_source();
  if (!source.empty() && !is_scene_hash(source))
    fail("the run's scene source ({} bytes) is not 32 hex digits", source.size());
  RunSettings s;
  s.bundles = r.bundles();
  s.seed = r.seed();
  s.grid = static_cast<int>(r.grid());
  s.rule = parse_update_rule(r.rule());
  s.burn_in = r.burn_in();
  s.directions = r.directions().empty() ? Directions::random : parse_directions(r.directions());
  s.control_variate = !r.no_control_variate();
  s.shots_per_bundle = r.shots_per_bundle();
  s.shot_resolution = static_cast<int>(r.shot_resolution());
  s.exchange_every = r.exchange_every();
  s.fraction = r.exchange_fraction();
  s.topology = parse_topology(r.topology());
  s.mode = parse_mode(r.mode());
  s.chunks = static_cast<uint32_t>(r.chunk_starts_size());
  s.mesh_options.target_patches = r.target_patches();
  s.mesh_options.max_edge = r.max_edge();
  check(s);
  return s;
}

RunSettings settings_of(const wire::Checkpoint& c) {
  RunSettings s = from_wire(c.run());
  s.balance = c.balance();
  s.time_limit_s = c.time_limit_s();
  s.target_error = c.target_error();
  check(s);
  return s;
}

void put_settings(wire::Checkpoint& c, const RunSettings& s, const wire::Run& run) {
  *c.mutable_run() = run;
  c.set_balance(s.balance);
  c.set_time_limit_s(s.time_limit_s);
  c.set_target_error(s.target_error);
}

SolverOptions solver_options(const RunSettings& s, const PatchMesh& mesh, uint64_t chain_id) {
  SolverOptions so;
  so.seed = s.seed;
  so.grid = run_grid(s, mesh);
  so.rule = s.rule;
  so.burn_in = s.burn_in;
  so.directions = s.directions;
  so.control_variate = s.control_variate;
  so.chain_id = chain_id;
  so.track_error = so.rule == UpdateRule::chain && mesh.size() <= kTrackErrorMaxPatches;
  so.shots_per_bundle = s.shots_per_bundle;
  so.shot_resolution = s.shot_resolution;
  return so;
}

PolicyConfig policy_config(const RunSettings& s, const PatchMesh& mesh, uint32_t min_nodes) {
  check(s);
  return {.bundles = s.bundles, .exchange_every = s.exchange_every, .fraction = s.fraction, .topology = s.topology,
          .mode = s.mode, .rule = s.rule, .min_nodes = min_nodes,
          .grant_unit = grant_unit(mesh, s.directions, s.shots_per_bundle), .time_limit_s = s.time_limit_s,
          .target_error = s.target_error, .balance = s.balance,
          .batch_bundles = chain_memory(mesh, s.shots_per_bundle)};
}

Policy make_policy(const RunSettings& s, const PatchMesh& mesh, uint32_t min_nodes,
                   std::function<ExchangeSetting(const std::vector<uint32_t>& ready)> choose) {
  PolicyConfig pc = policy_config(s, mesh, min_nodes);
  if (s.exchange_every == kExchangeAuto) pc.choose = std::move(choose);
  const auto patches = static_cast<uint32_t>(mesh.size());
  std::vector<uint32_t> starts = chunk_starts(patches, std::min(s.chunks, patches));
  ChunkBounds bounds = chunk_bounds(mesh, starts);
  return Policy(pc, std::move(starts), error_weights(mesh), std::move(bounds));
}

Attributes run_attributes(const RunSettings& s, const RunOutcome& o, const PatchMesh& mesh, const std::string& scene,
                          bool cluster) {
  Attributes a = {
      {"sirad.version", std::string(kVersion)},
      {"sirad.scene", scene},
      {"sirad.scene_hash", mesh.hash},
      {"sirad.patches", static_cast<int64_t>(mesh.size())},
      {"sirad.bundles", static_cast<int64_t>(o.bundles)},
      {"sirad.grid", static_cast<int64_t>(o.grid)},
      {"sirad.seed", std::to_string(s.seed)},
      {"sirad.rule", std::string(to_string(s.rule))},
      {"sirad.directions", std::string(to_string(s.directions))},
      {"sirad.control_variate", std::string(s.control_variate ? "on" : "off")},
      {"sirad.shots_per_bundle", s.shots_per_bundle},
      {"sirad.nodes", static_cast<int64_t>(o.nodes)},
      {"sirad.exchange_every", exchange_every_name(o.exchange_every)},
      {"sirad.exchange_fraction", o.fraction},
      {"sirad.ended_by", o.ended_by},
  };
  if (o.seconds > 0) {
    const double rate = static_cast<double>(o.bundles) / o.seconds;
    a.emplace_back("sirad.seconds", o.seconds);
    a.emplace_back("sirad.bundles_per_s", rate);
    a.emplace_back("sirad.patch_bundles_per_s", rate * static_cast<double>(mesh.size()));
    a.emplace_back("sirad.crossings_per_s", static_cast<double>(o.crossings) / o.seconds);
  }
  if (cluster) {
    a.emplace_back("sirad.topology", std::string(s.topology == Topology::star ? "star" : "ring"));
    a.emplace_back("sirad.mode", std::string(s.mode == Mode::sync ? "sync" : "async"));
  }
  return a;
}

}  // namespace sirad::cluster
