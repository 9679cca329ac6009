// sirad: the command line. `sirad render SCENE` solves a scene on one OpenCL device (or an
// embedded cluster of N nodes) and writes NAME.exr, NAME.png, NAME.ply and NAME.glb; `sirad
// emulate` runs a cluster in virtual time; `sirad devices` lists the OpenCL devices; the farm's
// client submits, lists and cancels jobs. This file declares the flags and hands each
// subcommand's arguments to its code (cli/commands.h).
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "cli/commands.h"
#include "cli/program.h"
#include "cli/run_flags.h"
#include "engine/version.h"
#include "farm/farm_client.h"
#include "farm/view_server.h"
#include "util/error.h"

namespace sirad {
namespace {

using namespace cli;

CLI::App* add_model_command(CLI::App& app, ModelArgs& m) {
  auto* cmd = app.add_subcommand("model", "The paper's cost and error model: predicted error and effective samples (CSV)");
  cmd->add_option("--processors", m.setup.processors, "P")->check(CLI::Range(1, 1000000))->capture_default_str();
  cmd->add_option("--exchange-every", m.setup.exchange_every, "I (0: never)")->check(CLI::Range(uint64_t{0}, uint64_t{1} << 40))->capture_default_str();
  cmd->add_option("--fraction", m.setup.fraction, "S in (0, 1]")->check(cli::finite_in(1e-9, 1.0))->capture_default_str();
  cmd->add_option("--contraction", m.scene_params.contraction, "a in [0, 1)")->check(cli::finite_in(0.0, 0.999999))->capture_default_str();
  cmd->add_option("--sigma", m.scene_params.sigma_ratio, "sigma_1 / C")->check(cli::positive())->capture_default_str();
  cmd->add_option("--t-iteration", m.costs.t_iteration, "T_i, seconds per iteration")->check(cli::positive())->capture_default_str();
  m.t_exchange_flag = cmd->add_option("--t-exchange", m.costs.t_exchange, "T_e, seconds per exchange with one processor")
                          ->check(cli::non_negative())
                          ->capture_default_str();
  cmd->add_option("--time", m.time, "T, seconds")->check(cli::positive())->capture_default_str();
  cmd->add_option("--sweep", m.sweep, "none, processors (P = 1..max), period (I = 1..max) or fraction (S = k / max)")
      ->check(CLI::IsMember({"none", "processors", "period", "fraction"}))->capture_default_str();
  cmd->add_option("--max", m.max, "Sweep range, and the largest I searched for the best")->check(CLI::Range(uint64_t{1}, uint64_t{1000000}))->capture_default_str();
  cmd->add_option("--scene", m.scene, "Fit the contraction, sigma_1 / C and T_i on this scene's bundles (replacing those flags)");
  cli::add_run_flags(cmd, m.mesh, cli::kMeshFlags);  // the fitted scene's meshing
  cmd->add_option("--device", m.device, "OpenCL device for the fit");
  cmd->add_option("--time-to", m.time_to, "Also print the time each setup needs to reach this relative error (column time_to_error)")
      ->check(cli::finite_in(1e-9, 1e9));
  cmd->add_option("--from-run", m.from_run,
                  "A run's --status-json file: its P, I, S, time, T_i (busy / bundles) and T_e (idle / exchanges) are the setup");
  cmd->add_option("--profile", m.profile,
                  "T_e from this emulation profile's links (the nodes' and the coordinator's) for a sync exchange of "
                  "--state-patches patches (or the --scene's)");
  cmd->add_option("--state-patches", m.state_patches, "With --profile: the patches of the state exchanged")
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 31));
  return cmd;
}

CLI::App* add_reference_command(CLI::App& app, ReferenceArgs& r) {
  auto* cmd = app.add_subcommand("reference", "Independent reference solution (Embree rays, exact direct light); "
                                              "write NAME.exr, .png, .ply and NAME.ref.csv");
  cli::add_scene_argument(cmd, r.scene);
  cli::add_run_flags(cmd, r.mesh, cli::kMeshFlags);
  cmd->add_option("--rays", r.options.rays_per_patch, "Cosine-distributed rays per patch (all batches)")
      ->check(CLI::Range(1, 1 << 24))->capture_default_str();
  cmd->add_option("--light-samples", r.options.light_samples,
                  "Direct-light points per patch (all batches), each with one shadow ray per emitter triangle")
      ->check(CLI::Range(1, 1 << 24))->capture_default_str();
  cmd->add_option("--batches", r.options.batches, "Independent batches for the standard error")
      ->check(CLI::Range(2, 1024))->capture_default_str();
  cmd->add_option("--seed", r.options.seed, "Seed")->capture_default_str();
  cmd->add_option("--threads", r.options.threads, "Threads (0: all cores)")->check(CLI::Range(0, 1024))->capture_default_str();
  cli::add_output_flags(cmd, r.output);
  cmd->add_flag("-q,--quiet", r.quiet, "No progress output");
  return cmd;
}

CLI::App* add_image_command(CLI::App& app, ImageArgs& a) {
  auto* cmd = app.add_subcommand("image", "Image a solved scene (the PLY or glb sirad wrote) by a final gather: direct light traced, "
                                          "indirect from the solution; write NAME.exr (passes direct, indirect) and NAME.png");
  cmd->add_option("solution", a.solution, "The solution: the .ply or .glb written by sirad render, reference or a coordinator")->required();
  auto* camera = cmd->add_option("--camera", a.camera,
                                 "The view: \"eye X Y Z look X Y Z up X Y Z fov DEG\" (default: the solution's camera)");
  cmd->add_option("--cameras", a.cameras,
                  "A walkthrough: one view per line (as --camera; blank lines and # comments skipped), written NAME-0001 ...")
      ->excludes(camera);
  a.gather.width = a.gather.height = 0;  // settled from the solution's camera (cli::settle_image_size)
  cmd->add_option("--width", a.gather.width, "Image width (default: the camera's aspect times the height)")->check(CLI::Range(1, kMaxImageSide));
  cmd->add_option("--height", a.gather.height, "Image height (default: 512, or the width over the camera's aspect)")
      ->check(CLI::Range(1, kMaxImageSide));
  cmd->add_option("--spp", a.gather.spp, "Samples per pixel (each: a primary ray, an emitter sample, a gather ray)")
      ->check(CLI::Range(1, 65536))->capture_default_str();
  cmd->add_option("--seed", a.gather.seed, "Seed")->capture_default_str();
  cmd->add_option("--threads", a.gather.threads, "Threads (0: all cores)")->check(CLI::Range(0, 1024))->capture_default_str();
  cmd->add_option("--exposure", a.exposure, "PNG exposure in stops")->check(cli::finite_in(-64.0, 64.0));
  cmd->add_option("--out", a.out, "Output name: NAME.exr and NAME.png (default: the solution's name with -image)");
  cmd->add_flag("-q,--quiet", a.quiet, "No progress output");
  return cmd;
}

// The flags of a run, shared by `render`, `bake` and `emulate` (the cluster flags: with --nodes).
void add_run_options(CLI::App* cmd, RenderArgs& r) {
  cli::add_scene_argument(cmd, r.scene);
  cli::add_run_flags(cmd, r.run);
  cli::add_output_flags(cmd, r.output);
  cmd->add_option("--device", r.device, "OpenCL device: P:D, or part of its name (env SIRAD_DEVICE)");
  add_transfer_flag(cmd, r.transfer);
  cmd->add_flag("-q,--quiet", r.quiet, "No progress output");
}

// `sirad bake`: render's flags and the lightmap's (the lightmap always on).
void add_warm_start(CLI::App* cmd, RenderArgs& r) {
  cmd->add_option("--warm-start", r.warm_start,
                  "Start from a previous run's PLY (an earlier version of the scene): where a patch is where one of its "
                  "patches was, its solution serves as a control variate; the answer is the new scene's (one node, chain rule, "
                  "no first shot)");
}

CLI::App* add_bake_command(CLI::App& app, RenderArgs& b) {
  auto* cmd = app.add_subcommand("bake", "Solve a scene and bake its light into a lightmap: NAME-lightmap.exr (half-float radiance), "
                                         "NAME-lightmap.png, NAME-baked.glb (TEXCOORD_1, the lightmap shown unlit), and render's outputs");
  add_run_options(cmd, b);
  add_warm_start(cmd, b);
  cli::add_lightmap_flags(cmd, b.output.lightmap, false);
  return cmd;
}

// `sirad keygen` and `sirad profile`.
struct ToolArgs {
  std::string profile_path, profile_prefix = "local-", keygen_name;
  int profile_nodes = 4;
};

std::pair<CLI::App*, CLI::App*> add_tool_commands(CLI::App& app, ToolArgs& t) {
  auto* keygen = app.add_subcommand("keygen", "Make a CURVE key pair for a TCP cluster: NAME.key (public) and NAME.key_secret (mode 0600)");
  keygen->add_option("name", t.keygen_name, "Path and base name of the two files")->required();
  auto* profile = app.add_subcommand("profile", "Check an emulation profile; print the link of each node");
  profile->add_option("file", t.profile_path, "Profile (YAML)")->required();
  profile->add_option("--nodes", t.profile_nodes, "Nodes to list")->check(CLI::Range(1, 4096))->capture_default_str();
  profile->add_option("--name-prefix", t.profile_prefix, "Node names are PREFIX0, PREFIX1, ...")->capture_default_str();
  return {keygen, profile};
}

struct ViewArgs {
  std::string glb, host = "127.0.0.1";
  int port = 0;
};

CLI::App* add_view_command(CLI::App& app, ViewArgs& v) {
  auto* cmd = app.add_subcommand("view", "Show a result glb (sirad render's or bake's) in 3D on a local page (three.js): orbit, walk, exposure");
  cmd->add_option("glb", v.glb, "The glb")->required();
  cmd->add_option("--port", v.port, "Port (0: any free one; the page's address is printed)")->check(CLI::Range(0, 65535));
  cmd->add_option("--host", v.host, "Address to listen on")->capture_default_str();
  return cmd;
}

int run(int argc, char** argv) {
  CLI::App app{"sirad: diffuse global illumination by stochastic iteration with bundles of parallel lines"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Every subcommand's options too (what the man page shows)");
  app.set_version_flag("--version", [] { return version_text("sirad"); }, "Version, git commit and OpenCL platforms");
  RenderArgs r;
  auto* render_cmd = app.add_subcommand("render", "Solve a scene on one OpenCL device (or N embedded nodes); write NAME.exr, .png, .ply, .glb");
  add_run_options(render_cmd, r);
  render_cmd->add_option("--nodes", r.nodes, "Embedded cluster: N local nodes over ZeroMQ inproc (0: single node)")
      ->check(CLI::Range(0, 64));
  render_cmd->add_option("--status-json", r.status_json, "With --nodes: rewrite this file with the run's status every second");
  render_cmd->add_option("--profile", r.profile, "With --nodes: network emulation profile (YAML; nodes are named local-0, local-1, ...)");
  add_warm_start(render_cmd, r);
  cli::add_lightmap_flags(render_cmd, r.output.lightmap, true);
  RenderArgs bake_args;
  auto* bake_cmd = add_bake_command(app, bake_args);
  EmulateArgs e;
  auto* emulate_cmd = app.add_subcommand(
      "emulate", "Run a cluster of N nodes in virtual time on this machine (real bundles, emulated clocks and links); write NAME.exr, .png, .ply");
  add_run_options(emulate_cmd, e.run);
  emulate_cmd->add_option("--nodes", e.run.nodes, "Emulated nodes (default: the profile's node entries)")
      ->check(CLI::Range(1, 4096));
  emulate_cmd->add_option("--profile", e.run.profile, "Emulation profile (YAML): speeds and links; nodes are named emu-0, emu-1, ...");
  emulate_cmd->add_option("--bundle-ms", e.bundle_ms,
                          "Milliseconds of one bundle at speed 1 (default: measured before the run; fix it for a reproducible timeline)")
      ->check(cli::positive());
  emulate_cmd->add_option("--tile-ms", e.tile_ms,
                          "With --final-gather: milliseconds of one 32 x 32 tile at speed 1 (default: measured once the "
                          "solution is in; fix it for a reproducible timeline)")
      ->check(cli::positive());
  emulate_cmd->add_option("--nodes-csv", e.nodes_csv, "Write the per-node figures (bundles, busy, idle, utilisation) as CSV");
  emulate_cmd->add_option("--timeline", e.timeline, "Write the virtual timeline (every grant, report, update, stop; the image's tiles and pixels) as CSV");
  ReferenceArgs ref_args;
  auto* reference_cmd = add_reference_command(app, ref_args);
  ModelArgs model_args;
  auto* model_cmd = add_model_command(app, model_args);
  ImageArgs image_args;
  auto* image_cmd = add_image_command(app, image_args);
  ViewArgs view_args;
  auto* view_cmd = add_view_command(app, view_args);
  app.add_subcommand("devices", "List the OpenCL devices");
  ToolArgs tools;
  auto [keygen_cmd, profile_cmd] = add_tool_commands(app, tools);

  // The farm's client (farm/farm_client.h).
  cli::FarmAddress farm;
  auto add_farm = [&](CLI::App* cmd, bool token) {
    cmd->add_option("--farm", farm.farm, "The farm: http://HOST:PORT, or its folder on this machine")->required();
    if (token)
      cmd->add_option("--token-file", farm.token_file, "The farm's token (default: SIRAD_FARM_TOKEN, or the farm folder's)");
  };
  std::string submit_scene, submit_name;
  int submit_priority = 0;
  auto* submit_cmd = app.add_subcommand("submit", "Queue a job on a farm (sirad-coordinator --serve): SCENE and its run and output flags, and --min-nodes N, --max-nodes N (the most nodes it takes; 0: every node)");
  cli::add_scene_argument(submit_cmd, submit_scene);
  add_farm(submit_cmd, true);
  submit_cmd->add_option("--priority", submit_priority, "Higher runs first (default 0)")->check(CLI::Range(-1000000, 1000000));
  submit_cmd->add_option("--name", submit_name, "The job's name, and its outputs' (default: the scene's)");
  submit_cmd->allow_extras();  // the job's own flags, checked against the run and output flags
  auto* jobs_cmd = app.add_subcommand("jobs", "List a farm's jobs and their progress");
  add_farm(jobs_cmd, false);
  uint64_t cancel_id = 0;
  auto* cancel_cmd = app.add_subcommand("cancel", "Cancel a farm's job (a running one stops at its checkpoint)");
  cancel_cmd->add_option("id", cancel_id, "The job's id (sirad jobs)")->required();
  add_farm(cancel_cmd, true);

  if (std::optional<int> exit = cli::parse_command_line(app, argc, argv, "sirad")) return *exit;
  auto given = [](const CLI::App* cmd) { return cli::given_flags(cmd); };
  if (render_cmd->parsed()) {
    r.given = given(render_cmd);
    return render(r);
  }
  if (bake_cmd->parsed()) {
    bake_args.given = given(bake_cmd);
    bake_args.output.lightmap.on = true;
    return render(bake_args);
  }
  if (emulate_cmd->parsed()) {
    e.run.given = given(emulate_cmd);
    return emulate(e);
  }
  if (reference_cmd->parsed()) {
    ref_args.given = given(reference_cmd);
    return reference(ref_args);
  }
  if (image_cmd->parsed()) return image(image_args);
  if (view_cmd->parsed()) return view_command(view_args.glb, view_args.host, view_args.port);
  if (model_cmd->parsed()) {
    model_args.time_given = model_cmd->count("--time") > 0;
    model_args.given = given(model_cmd);
    return model_table(model_args);
  }
  if (profile_cmd->parsed()) return profile_table(tools.profile_path, tools.profile_nodes, tools.profile_prefix);
  if (keygen_cmd->parsed()) return keygen(tools.keygen_name);
  if (submit_cmd->parsed()) return cli::submit_job(farm, submit_scene, submit_cmd->remaining(), submit_name, submit_priority);
  if (jobs_cmd->parsed()) return cli::list_jobs(farm);
  if (cancel_cmd->parsed()) return cli::cancel_job(farm, cancel_id);
  return devices();
}

}  // namespace
}  // namespace sirad

int main(int argc, char** argv) {
  return sirad::cli::guarded("sirad", [&] { return sirad::run(argc, argv); });
}
