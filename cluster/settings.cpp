// sirad: a run's settings and their conversions (see settings.h).
#include "cluster/settings.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "cluster/policy.h"
#include "engine/version.h"
#include "scene/encoding.h"
#include "solver/error_estimate.h"
#include "util/error.h"
#include "util/numbers.h"

namespace sirad::cluster {

namespace {

// A number as the shortest text that reads back to exactly it.
std::string exact(double v) { return fmt::format("{}", v); }

bool on_off(const std::string& text) {
  if (text != "on" && text != "off") fail("{} is not on or off", text);
  return text == "on";
}

// The table. Rows are parsed in this order: --patches before --max-edge (which replaces its
// meshing), --rule before --directions (auto follows the rule).
const std::vector<SettingRow> kRows = {
    {.flag = "patches",
     .help = "Mesh to about this many patches (default 10000)",
     .type = "INT",
     .default_text = "10000",
     .parse = [](RunSettings& s, const std::string& t) {
       s.mesh_options.target_patches = static_cast<std::size_t>(integer_in(t, 1, int64_t{1} << 31));
       s.mesh_options.max_edge = 0;
     },
     .check = [](const RunSettings& s) {
       if (s.mesh_options.target_patches > kMaxTargetPatches)
         fail("target patches {} is above {}", s.mesh_options.target_patches, kMaxTargetPatches);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_target_patches(s.mesh_options.target_patches); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.mesh_options.target_patches = r.target_patches(); },
     .text = [](const RunSettings& s) { return s.mesh_options.target_patches > 0 ? std::to_string(s.mesh_options.target_patches) : std::string(); }},
    {.flag = "max-edge",
     .help = "Mesh so no patch edge is longer than this",
     .type = "FLOAT",
     .parse = [](RunSettings& s, const std::string& t) {
       s.mesh_options.max_edge = positive_real(t);
       s.mesh_options.target_patches = 0;
     },
     .check = [](const RunSettings& s) {
       if (!(s.mesh_options.max_edge >= 0) || !std::isfinite(s.mesh_options.max_edge))
         fail("max edge {:.6g} is not a finite length >= 0", s.mesh_options.max_edge);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_max_edge(s.mesh_options.max_edge); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.mesh_options.max_edge = r.max_edge(); },
     .text = [](const RunSettings& s) { return s.mesh_options.max_edge > 0 ? exact(s.mesh_options.max_edge) : std::string(); }},
    {.flag = "max-patches",
     .help = "Refuse a scene that meshes to more patches than this, before the mesh is made (default: 2^31 - 1)",
     .type = "INT",
     .parse = [](RunSettings& s, const std::string& t) {
       s.mesh_options.max_patches = static_cast<uint64_t>(integer_in(t, 1, static_cast<int64_t>(kMaxTargetPatches)));
     },
     .check = [](const RunSettings& s) {
       if (s.mesh_options.max_patches > kMaxTargetPatches)
         fail("max patches {} is above {}", s.mesh_options.max_patches, kMaxTargetPatches);
     },
     // Not in the wire's Run: a node meshes to the run's patch count and no more (node.cpp).
     .to_checkpoint = [](const RunSettings& s, wire::Checkpoint& c) { c.set_max_patches(s.mesh_options.max_patches); },
     .from_checkpoint = [](const wire::Checkpoint& c, RunSettings& s) { s.mesh_options.max_patches = c.max_patches(); },
     .text = [](const RunSettings& s) {
       return s.mesh_options.max_patches > 0 ? std::to_string(s.mesh_options.max_patches) : std::string();
     }},
    {.flag = "bundles",
     .help = "Bundles (random directions) to run; the cap with --target-error (default there: 1000000)",
     .type = "INT",
     .default_text = "1000",
     .show_default = true,
     .parse = [](RunSettings& s, const std::string& t) { s.bundles = static_cast<uint64_t>(integer_in(t, 1, int64_t{1} << 40)); },
     .check = [](const RunSettings& s) {
       if (s.bundles == 0 || s.bundles > kMaxBundles) fail("bundles {} is outside 1..{}", s.bundles, kMaxBundles);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_bundles(s.bundles); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.bundles = r.bundles(); },
     .text = [](const RunSettings& s) { return std::to_string(s.bundles); }},
    {.flag = "grid",
     .help = "Lines per side of a bundle (default: from the patch sizes)",
     .type = "INT",
     .parse = [](RunSettings& s, const std::string& t) { s.grid = static_cast<int>(integer_in(t, 2, kMaxGrid)); },
     .check = [](const RunSettings& s) {
       if (s.grid != 0 && (s.grid < 2 || s.grid > kMaxGrid)) fail("grid {} is outside 2..{} (0: auto)", s.grid, kMaxGrid);
     },
     .to_run = [](const RunSettings& s, const PatchMesh& mesh, wire::Run& r) { r.set_grid(static_cast<uint32_t>(run_grid(s, mesh))); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.grid = static_cast<int>(r.grid()); },
     .text = [](const RunSettings& s) { return s.grid > 0 ? std::to_string(s.grid) : std::string(); }},
    {.flag = "seed",
     .help = "Run seed",
     .type = "INT",
     .default_text = "1",
     .show_default = true,
     .parse = [](RunSettings& s, const std::string& t) {
       s.seed = unsigned_integer(t);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_seed(s.seed); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.seed = r.seed(); },
     .text = [](const RunSettings& s) { return std::to_string(s.seed); }},
    {.flag = "rule",
     .help = "Update rule: chain (default) or average (the paper's)",
     .type = "NAME",
     .choices = {"chain", "average"},
     .default_text = "chain",
     .parse = [](RunSettings& s, const std::string& t) { s.rule = parse_update_rule(t); },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_rule(to_string(s.rule)); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.rule = parse_update_rule(r.rule()); },
     .text = [](const RunSettings& s) { return std::string(to_string(s.rule)); }},
    {.flag = "directions",
     .help = "Bundle directions: auto (stratified under the chain rule, random under average), random or stratified",
     .type = "NAME",
     .choices = {"auto", "random", "stratified"},
     .default_text = "auto",
     .show_default = true,
     .parse = [](RunSettings& s, const std::string& t) {
       // auto: stratified under the chain rule, random under average (where stratification
       // biases: engine/bundle.cpp).
       s.directions = t == "auto" ? (s.rule == UpdateRule::chain ? Directions::stratified : Directions::random) : parse_directions(t);
       if (s.directions == Directions::stratified && s.rule != UpdateRule::chain)
         fail("stratified needs --rule chain (under average it biases the estimate: engine/bundle.cpp)");
     },
     .check = [](const RunSettings& s) {
       if (s.directions == Directions::stratified && s.rule != UpdateRule::chain)
         fail("stratified directions need the chain rule (under average they bias the estimate: engine/bundle.cpp)");
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_directions(to_string(s.directions)); },
     .from_run = [](const wire::Run& r, RunSettings& s) {
       s.directions = r.directions().empty() ? Directions::random : parse_directions(r.directions());
     },
     .text = [](const RunSettings& s) { return std::string(to_string(s.directions)); }},
    {.flag = "control-variate",
     .help = "The transport's constant control variate: on (default) or off (the plain estimator)",
     .type = "NAME",
     .choices = {"on", "off"},
     .default_text = "on",
     .show_default = true,
     .parse = [](RunSettings& s, const std::string& t) { s.control_variate = on_off(t); },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_no_control_variate(!s.control_variate); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.control_variate = !r.no_control_variate(); },
     .text = [](const RunSettings& s) { return std::string(s.control_variate ? "on" : "off"); }},
    {.flag = "burn-in",
     .help = "Chain bundles run before counting (default: auto)",
     .type = "INT",
     .parse = [](RunSettings& s, const std::string& t) { s.burn_in = static_cast<int>(integer_in(t, 0, kMaxBurnIn)); },
     .check = [](const RunSettings& s) {
       if (s.burn_in < -1 || s.burn_in > kMaxBurnIn) fail("burn-in {} is outside 0..{} (-1: auto)", s.burn_in, kMaxBurnIn);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_burn_in(s.burn_in); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.burn_in = r.burn_in(); },
     .text = [](const RunSettings& s) { return s.burn_in >= 0 ? std::to_string(s.burn_in) : std::string(); }},
    {.flag = "shots-per-bundle",
     .help = "First shot: hemicube shots from the emitters per bundle (0: off, the plain estimator)",
     .type = "FLOAT",
     .default_text = "0.25",
     .show_default = true,
     .parse = [](RunSettings& s, const std::string& t) { s.shots_per_bundle = real_in(t, 0.0, 1024.0); },
     .check = [](const RunSettings& s) { check_first_shot(s.shots_per_bundle, s.shot_resolution); },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_shots_per_bundle(s.shots_per_bundle); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.shots_per_bundle = r.shots_per_bundle(); },
     .text = [](const RunSettings& s) { return exact(s.shots_per_bundle); }},
    {.flag = "shot-resolution",
     .help = "First shot: hemicube side in pixels (0: from the mesh)",
     .type = "INT",
     .default_text = "0",
     .show_default = true,
     .parse = [](RunSettings& s, const std::string& t) {
       const int64_t v = integer_in(t, 0, 2048);
       if (v != 0 && (v < 4 || v % 2 != 0)) fail("must be 0 (auto) or even in [4, 2048] (got {})", t);
       s.shot_resolution = static_cast<int>(v);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_shot_resolution(static_cast<uint32_t>(s.shot_resolution)); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.shot_resolution = static_cast<int>(r.shot_resolution()); },
     .text = [](const RunSettings& s) { return std::to_string(s.shot_resolution); }},
    {.flag = "exchange-every",
     .help = "Bundles between exchanges, 'end', or 'auto' (chosen from the paper's model at the start: see sirad model)",
     .type = "N|end|auto",
     .default_text = "end",
     .show_default = true,
     .cluster = true,
     .parse = [](RunSettings& s, const std::string& t) { s.exchange_every = parse_exchange_every(t); },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_exchange_every(s.exchange_every); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.exchange_every = r.exchange_every(); },
     .text = [](const RunSettings& s) { return exchange_every_name(s.exchange_every); }},
    {.flag = "exchange-fraction",
     .help = "Fraction S of chunks per exchange",
     .type = "FLOAT",
     .default_text = "1",
     .show_default = true,
     .cluster = true,
     .parse = [](RunSettings& s, const std::string& t) { s.fraction = real_in(t, 1e-9, 1.0); },
     .check = [](const RunSettings& s) {
       if (!(s.fraction > 0 && s.fraction <= 1)) fail("exchange fraction {} is outside (0, 1]", s.fraction);
     },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_exchange_fraction(s.fraction); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.fraction = r.exchange_fraction(); },
     .text = [](const RunSettings& s) { return exact(s.fraction); }},
    {.flag = "topology",
     .help = "star or ring",
     .type = "NAME",
     .choices = {"star", "ring"},
     .default_text = "star",
     .show_default = true,
     .cluster = true,
     .parse = [](RunSettings& s, const std::string& t) { s.topology = parse_topology(t); },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_topology(s.topology == Topology::star ? "star" : "ring"); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.topology = parse_topology(r.topology()); },
     .text = [](const RunSettings& s) { return std::string(s.topology == Topology::star ? "star" : "ring"); }},
    {.flag = "mode",
     .help = "sync or async",
     .type = "NAME",
     .choices = {"sync", "async"},
     .default_text = "async",
     .show_default = true,
     .cluster = true,
     .parse = [](RunSettings& s, const std::string& t) { s.mode = parse_mode(t); },
     .to_run = [](const RunSettings& s, const PatchMesh&, wire::Run& r) { r.set_mode(s.mode == Mode::sync ? "sync" : "async"); },
     .from_run = [](const wire::Run& r, RunSettings& s) { s.mode = parse_mode(r.mode()); },
     .text = [](const RunSettings& s) { return std::string(s.mode == Mode::sync ? "sync" : "async"); }},
    {.flag = "balance",
     .help = "Grants sized to each node's speed, so unequal nodes finish them together: on or off (every grant I bundles)",
     .type = "NAME",
     .choices = {"on", "off"},
     .default_text = "on",
     .show_default = true,
     .cluster = true,
     .parse = [](RunSettings& s, const std::string& t) { s.balance = on_off(t); },
     .to_checkpoint = [](const RunSettings& s, wire::Checkpoint& c) { c.set_balance(s.balance); },
     .from_checkpoint = [](const wire::Checkpoint& c, RunSettings& s) { s.balance = c.balance(); },
     .text = [](const RunSettings& s) { return std::string(s.balance ? "on" : "off"); }},
    {.flag = "time-limit",
     .help = "End the run early after this long (seconds)",
     .type = "SECONDS",
     .parse = [](RunSettings& s, const std::string& t) { s.time_limit_s = non_negative_real(t); },
     .check = [](const RunSettings& s) {
       if (!(s.time_limit_s >= 0 && s.time_limit_s <= kMaxSeconds))
         fail("time limit {:.6g} s is outside 0..{:.0e} s", s.time_limit_s, kMaxSeconds);
     },
     .to_checkpoint = [](const RunSettings& s, wire::Checkpoint& c) { c.set_time_limit_s(s.time_limit_s); },
     .from_checkpoint = [](const wire::Checkpoint& c, RunSettings& s) { s.time_limit_s = c.time_limit_s(); },
     .text = [](const RunSettings& s) { return exact(s.time_limit_s); }},
    {.flag = "target-error",
     .help = "End the run at this relative error estimate (one node: batch means; 2+ nodes with --exchange-every: the "
             "nodes' spread)",
     .type = "FLOAT",
     .parse = [](RunSettings& s, const std::string& t) { s.target_error = real_in(t, 0.0, 1.0); },
     .check = [](const RunSettings& s) {
       if (!(s.target_error >= 0 && s.target_error <= 1)) fail("target error {} is outside [0, 1]", s.target_error);
     },
     .to_checkpoint = [](const RunSettings& s, wire::Checkpoint& c) { c.set_target_error(s.target_error); },
     .from_checkpoint = [](const wire::Checkpoint& c, RunSettings& s) { s.target_error = c.target_error(); },
     .text = [](const RunSettings& s) { return exact(s.target_error); }},
    {.flag = "chunks",
     .help = "Chunks of patches exchanged separately",
     .type = "INT",
     .default_text = "16",
     .show_default = true,
     .cluster = true,
     .parse = [](RunSettings& s, const std::string& t) { s.chunks = static_cast<uint32_t>(integer_in(t, 1, proto::kMaxChunks)); },
     .check = [](const RunSettings& s) {
       if (s.chunks == 0 || s.chunks > proto::kMaxChunks) fail("chunks {} is outside 1..{}", s.chunks, proto::kMaxChunks);
     },
     // On the wire as the chunks' starts (to_wire's `chunk_starts`).
     .from_run = [](const wire::Run& r, RunSettings& s) { s.chunks = static_cast<uint32_t>(r.chunk_starts_size()); },
     .text = [](const RunSettings& s) { return std::to_string(s.chunks); }},
};

}  // namespace

const std::vector<SettingRow>& setting_rows() { return kRows; }

void check(const RunSettings& s) {
  for (const SettingRow& row : kRows)
    if (row.check) row.check(s);
}

SettingsText settings_text(const RunSettings& s) {
  SettingsText out;
  for (const SettingRow& row : kRows)
    if (std::string t = row.text(s); !t.empty()) out.emplace_back(row.flag, std::move(t));
  return out;
}

RunSettings settings_from_text(const SettingsText& text, const std::string& origin) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    const std::string& flag = text[i].first;
    if (std::none_of(kRows.begin(), kRows.end(), [&](const SettingRow& row) { return row.flag == flag; }))
      fail("{}: '{}' is not a run setting", origin, flag.substr(0, 40));
    for (std::size_t j = 0; j < i; ++j)
      if (text[j].first == flag) fail("{}: '{}' is given twice", origin, flag);
  }
  RunSettings s;
  for (const SettingRow& row : kRows) {
    auto given = std::find_if(text.begin(), text.end(), [&](const auto& t) { return t.first == row.flag; });
    if (given == text.end()) continue;
    try {
      row.parse(s, given->second);
    } catch (const Error& e) {
      fail("{}: {}: {}", origin, row.flag, e.what());
    }
  }
  try {
    check(s);
  } catch (const Error& e) {
    fail("{}: {}", origin, e.what());
  }
  return s;
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
  for (std::size_t c = 0; c + 1 < chunk_starts.size(); ++c) run.add_chunk_starts(chunk_starts[c]);
  run.set_patches(static_cast<uint32_t>(mesh.size()));
  for (const SettingRow& row : kRows)
    if (row.to_run) row.to_run(s, mesh, run);
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
  for (const SettingRow& row : kRows)
    if (row.from_run) row.from_run(r, s);
  check(s);
  return s;
}

RunSettings settings_of(const wire::Checkpoint& c) {
  RunSettings s = from_wire(c.run());
  for (const SettingRow& row : kRows)
    if (row.from_checkpoint) row.from_checkpoint(c, s);
  check(s);
  return s;
}

void put_settings(wire::Checkpoint& c, const RunSettings& s, const wire::Run& run) {
  *c.mutable_run() = run;
  for (const SettingRow& row : kRows)
    if (row.to_checkpoint) row.to_checkpoint(s, c);
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

DeadlineRules grant_deadlines(const ProcessSettings& p) {
  DeadlineRules r = p.deadlines;
  r.slack_s = std::max(r.slack_s, p.heartbeat_ms * 1e-3 * p.liveness);
  return r;
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
