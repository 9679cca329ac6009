// sirad: `sirad-coordinator SCENE` (see coordinator_command.h).
#include "cli/coordinator_command.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <fmt/format.h>

#include "cli/stop_signals.h"
#include "cluster/checkpoint.h"
#include "cluster/live_view.h"
#include "cluster/policy.h"
#include "coordinator/coordinator.h"
#include "coordinator/listener.h"
#include "io/results.h"
#include "scene/check.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::cli {

int coordinate_command(CoordinatorArgs a) {
  if (a.scene.empty()) fail("a scene is required (or --serve DIR)");
  std::string out = a.output.out.empty() ? std::filesystem::path(a.scene).stem().string() : a.output.out;
  check_output_name(out, "--out");
  if (!a.ledger.empty()) check_file_name(a.ledger, "--ledger");
  if (!a.checkpoint.empty()) check_file_name(a.checkpoint, "--checkpoint");
  if (!a.status_json.empty()) check_file_name(a.status_json, "--status-json");
  cluster::RunConfig rc;
  std::optional<wire::Checkpoint> resumed;
  if (!a.resume.empty()) {
    // The run's settings are the checkpoint's: a flag that would change them is a mistake.
    for (const std::string& flag : a.run_flags)
      if (a.given.count(flag)) fail("{} with --resume: a resumed run keeps the checkpoint's settings", flag);
    resumed = cluster::read_checkpoint(a.resume);
    static_cast<cluster::RunSettings&>(rc) = cluster::settings_of(*resumed);
    rc.resume = &*resumed;
    if (a.checkpoint.empty()) a.checkpoint = a.resume;
    // The outputs the run was started for, unless this command names its own.
    const bool outputs_given = std::any_of(a.output_flags.begin(), a.output_flags.end(),
                                           [&](const std::string& f) { return f != "--out" && a.given.count(f); });
    if (!outputs_given)
      parse_output_args({resumed->output_args().begin(), resumed->output_args().end()}, a.output, a.resume);
  } else {
    static_cast<cluster::RunSettings&>(rc) = settings_from(a.run, a.given);
    if (std::string why = cluster::target_error_problem(rc); !why.empty()) fail("{}", why);
  }
  rc.scene = load_scene(a.scene, a.output.import());
  settle_image_size(a.output, rc.scene);
  rc.min_nodes = static_cast<uint32_t>(a.min_nodes);
  rc.timeout_s = a.timeout;
  rc.heartbeat_ms = static_cast<uint32_t>(a.heartbeat_ms);
  rc.liveness = static_cast<uint32_t>(a.liveness);
  if (!a.profile.empty()) rc.profile = emulation::load_profile(a.profile);
  cluster::check_real_run(rc);
  rc.emulate_bandwidth = !a.network_bandwidth;
  rc.checkpoint = a.checkpoint;
  rc.checkpoint_every_s = a.checkpoint_every;
  rc.output_args = output_args(a.output);
  PatchMesh mesh = mesh_scene(rc.scene, rc.mesh_options);
  const SceneCheck check = check_scene(rc.scene, mesh, camera_flag(a.output.camera), "--camera");
  if (resumed && resumed->run().scene_hash() != mesh.hash)
    fail("{}: the checkpoint is of scene {}; {} meshes to {} (the same file, --patches and --two-sided?)", a.resume,
         resumed->run().scene_hash(), a.scene, mesh.hash);
  for (const std::string& w : check.warnings) std::fprintf(stderr, "sirad-coordinator: warning: %s\n", w.c_str());
  const auto [keys, allow] = coordinator::server_keys(a.listen, a.curve_secret, a.allow_file, a.insecure);
  if (a.check_config) {
    std::printf("sirad-coordinator: config ok: %s, %zu patches, %lld bundles, exchange every %s, S %g, %s, %s%s%s\n",
                a.scene.c_str(), mesh.size(), static_cast<long long>(rc.bundles), cluster::exchange_every_name(rc.exchange_every).c_str(),
                rc.fraction, rc.topology == cluster::Topology::star ? "star" : "ring", rc.mode == cluster::Mode::sync ? "sync" : "async",
                a.profile.empty() ? "" : ", profile ", a.profile.c_str());
    return 0;
  }
  cluster::StatusReporter reporter(a.quiet, a.status_json);
  rc.status_every_s = 0.25;
  const ResultOptions shown = result_options(a.output);
  rc.final_gather = final_gather_of(shown);  // the image's tiles rendered by the nodes
  rc.status = std::ref(reporter);

  zmq::context_t context;
  coordinator::Listener listener(context, a.listen, keys, allow, mesh.size(), a.insecure, a.endpoint_file,
                    fmt::format("{}: {} patches, {} bundles", a.scene, mesh.size(), rc.bundles));
  zmq::socket_t& router = listener.router;
  rc.interrupt = &stop_on_signals();
  auto start = std::chrono::steady_clock::now();
  cluster::RunResult result = cluster::coordinate(router, rc, mesh, &*listener.bytes);
  reporter.finish();
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!a.ledger.empty()) {  // first: the ledger stays with the solution should the image have failed
    write_file_atomic(a.ledger, cluster::ledger_csv(result));
    std::printf("wrote %s\n", std::filesystem::absolute(a.ledger).c_str());
  }
  ResultFiles files = write_results(
      out, mesh, result.radiosity, shown, cluster::run_attributes(rc, cluster::outcome_of(result), mesh, a.scene, true),
      result.image ? &*result.image : nullptr, result.image_error);
  std::fputs(wrote_lines(files).c_str(), stdout);
  std::fputs(cluster::cluster_summary(result, mesh.size(), seconds).c_str(), stdout);
  if (result.ended_by != "budget") std::printf("ended early: %s\n", result.ended_by.c_str());
  if (result.bundles_lost) {  // the outputs are written: the run is not what was asked
    std::fprintf(stderr, "sirad-coordinator: error: %s\n", cluster::Policy::lost_reason(*result.bundles_lost).c_str());
    return 1;
  }
  return 0;
}

}  // namespace sirad::cli
