// sirad-coordinator: serves one run of a scene to the nodes that connect, then writes the
// outputs of the single-node solver (NAME.exr, NAME.png, NAME.ply).
//   sirad-coordinator SCENE --listen tcp://*:5555 [--bundles K --patches N --grid R --seed S
//     --out NAME --exchange-every I|end --exchange-fraction S --topology star|ring
//     --mode sync|async --profile FILE --min-nodes P --chunks C --endpoint-file FILE
//     --timeout SECONDS --heartbeat-ms MS --liveness N --status-json FILE --check-config]
//     [--curve-secret FILE --allow FILE | --insecure]   (one of them over tcp://)
//     [--checkpoint FILE --checkpoint-every SECONDS] [--resume CHECKPOINT]
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <optional>

#include <CLI/CLI.hpp>

#include "core/scene_check.h"
#include "coordinator/checkpoint.h"
#include "coordinator/coordinator.h"
#include "coordinator/live_view.h"
#include "core/atomic_file.h"
#include "core/bundle.h"
#include "core/error.h"
#include "core/results.h"
#include "proto/security.h"
#include "proto/transport.h"

using namespace sirad;

namespace {
std::atomic<bool> interrupted{false};
void on_signal(int) { interrupted = true; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sirad-coordinator: orchestrates sirad nodes solving one scene"};
  std::string scene_spec, listen = "tcp://*:5555", out, exchange_every = "end", topology = "star", mode = "async",
                          rule = "chain", directions = "auto", control_variate = "on", endpoint_file, status_json, profile,
                          balance = "on", curve_secret, allow_file, ledger, checkpoint, resume;
  double checkpoint_every = 10;
  int64_t bundles = 1000, patches = 10000;
  std::optional<int> grid;
  uint64_t seed = 1;
  double fraction = 1.0, timeout = 0, time_limit = 0, target_error = 0, shots_per_bundle = kDefaultShotsPerBundle;
  int shot_resolution = 0;
  int min_nodes = 1, chunks = 16, width = 512, height = 512, heartbeat_ms = 1000, liveness = 3;
  bool check_config = false, quiet = false, network_bandwidth = false, insecure = false, two_sided = false;
  app.add_option("scene", scene_spec, "Built-in scene (cornell, furnace) or an .obj file")->required();
  app.add_option("--listen", listen, "ZeroMQ endpoint to bind")->capture_default_str();
  std::string camera;
  app.add_option("--camera", camera, "The view of the images: \"eye X Y Z look X Y Z up X Y Z fov DEG\" (default: the scene's, else one chosen to see the most)");
  app.add_flag("--two-sided", two_sided,
               "Every surface two-sided, as in Cycles: both sides receive, reflect and emit (per material: MTL sirad_two_sided 1)");
  app.add_option("--bundles", bundles, "Bundles in the run")->check(CLI::Range(int64_t{1}, int64_t{1} << 40))->capture_default_str();
  app.add_option("--patches", patches, "Mesh to about this many patches")->check(CLI::Range(int64_t{1}, int64_t{1} << 31))->capture_default_str();
  app.add_option("--grid", grid, "Lines per side of a bundle (default: from the patch sizes)")->check(CLI::Range(2, 8192));
  app.add_option("--seed", seed, "Run seed")->capture_default_str();
  app.add_option("--out", out, "Output name (default: scene name)");
  app.add_option("--rule", rule, "chain or average")->check(CLI::IsMember({"chain", "average"}))->capture_default_str();
  app.add_option("--directions", directions, "Bundle directions: auto (stratified under the chain rule, random under average), random or stratified")
      ->check(CLI::IsMember({"auto", "random", "stratified"}))->capture_default_str();
  app.add_option("--control-variate", control_variate, "The transport's constant control variate: on or off")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  app.add_option("--shots-per-bundle", shots_per_bundle, "First shot: hemicube shots from the emitters per bundle (0: off)")
      ->check(CLI::Range(0.0, 1024.0))->capture_default_str();
  app.add_option("--shot-resolution", shot_resolution, "First shot: hemicube side in pixels (0: from the mesh)")
      ->check(CLI::Range(0, 2048))->capture_default_str();
  app.add_option("--exchange-every", exchange_every, "Bundles between exchanges, 'end', or 'auto' (chosen from the paper's model when the nodes are ready)")->capture_default_str();
  app.add_option("--exchange-fraction", fraction, "Fraction S of chunks per exchange")->check(CLI::Range(1e-9, 1.0))->capture_default_str();
  app.add_option("--topology", topology, "star or ring")->check(CLI::IsMember({"star", "ring"}))->capture_default_str();
  app.add_option("--mode", mode, "sync or async")->check(CLI::IsMember({"sync", "async"}))->capture_default_str();
  app.add_option("--balance", balance, "Grants sized to each node's speed, so unequal nodes finish them together: on or off")
      ->check(CLI::IsMember({"on", "off"}))->capture_default_str();
  app.add_option("--min-nodes", min_nodes, "Nodes ready before the first grant")->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--chunks", chunks, "Chunks of patches exchanged separately")->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--width", width, "Image width")->check(CLI::Range(1, 16384))->capture_default_str();
  app.add_option("--height", height, "Image height")->check(CLI::Range(1, 16384))->capture_default_str();
  app.add_option("--endpoint-file", endpoint_file, "Write the bound endpoint here (for scripts: tcp://*:0 picks a port)");
  app.add_option("--status-json", status_json, "Rewrite this file with the run's status every second");
  app.add_option("--ledger", ledger, "At the end, write which node ran which bundle indices (CSV: node,name,first,last)");
  app.add_option("--timeout", timeout, "Fail if the run takes longer (seconds; 0: never)")->check(CLI::NonNegativeNumber);
  app.add_option("--time-limit", time_limit, "End the run early after this long (seconds; 0: never)")->check(CLI::NonNegativeNumber);
  app.add_option("--target-error", target_error,
                 "End the run early at this relative error estimate (needs 2+ nodes and --exchange-every)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--profile", profile, "Network emulation profile (YAML; see deploy/profiles/)");
  app.add_option("--heartbeat-ms", heartbeat_ms, "Heartbeat interval")->check(CLI::Range(10, 60000))->capture_default_str();
  app.add_option("--liveness", liveness, "Heartbeats a node may miss before it is dead")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_flag("--bandwidth-by-network", network_bandwidth,
               "The network limits bandwidth (tc); do not emulate the profile's up/down rates");
  auto* secret_opt = app.add_option("--curve-secret", curve_secret,
                                    "This coordinator's CURVE secret key file (NAME.key_secret from sirad keygen; mode 0600)");
  auto* allow_opt = app.add_option("--allow", allow_file, "Allow list: the node public keys admitted, one Z85 key (and a name) per line");
  secret_opt->needs(allow_opt);
  allow_opt->needs(secret_opt);
  app.add_flag("--insecure", insecure, "Over TCP without CURVE: no authentication, no encryption (says so on start)");
  app.add_option("--checkpoint", checkpoint,
                 "Write the run's checkpoint here (atomically) every --checkpoint-every seconds and on SIGTERM/SIGINT");
  app.add_option("--checkpoint-every", checkpoint_every, "Seconds between checkpoints")
      ->check(CLI::Range(0.1, 86400.0))->capture_default_str();
  app.add_option("--resume", resume,
                 "Continue the run of this checkpoint (its settings; the same scene), checkpointing to it unless --checkpoint");
  app.add_flag("--check-config", check_config, "Check the flags, scene, profile and output place; run nothing");
  app.add_flag("-q,--quiet", quiet, "No progress view");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "sirad-coordinator: error: %s (see sirad-coordinator --help)\n", e.what());
    return 2;
  }
  try {
    if (out.empty()) out = std::filesystem::path(scene_spec).stem().string();
    check_output_name(out);
    if (!ledger.empty()) check_output_name(ledger, "--ledger");
    if (!checkpoint.empty()) check_output_name(checkpoint, "--checkpoint");
    cluster::RunConfig rc;
    rc.scene = load_scene(scene_spec, {.two_sided = two_sided});
    rc.mesh_options.target_patches = static_cast<std::size_t>(patches);
    // --target-error without --bundles lifts the default cap, as `sirad render` does.
    rc.bundles = static_cast<uint64_t>(target_error > 0 && app.count("--bundles") == 0 ? 1000000 : bundles);
    if (target_error > 0 && exchange_every == "end" && resume.empty())
      fail("--target-error needs --exchange-every (its estimate is the spread of the nodes' exchanged states)");
    rc.seed = seed;
    rc.grid = grid.value_or(0);
    rc.rule = parse_update_rule(rule);
    rc.directions = resolve_directions(directions, rc.rule);
    rc.control_variate = control_variate == "on";
    check_first_shot(shots_per_bundle, shot_resolution);
    rc.shots_per_bundle = shots_per_bundle;
    rc.shot_resolution = shot_resolution;
    rc.exchange_every = cluster::parse_exchange_every(exchange_every);
    rc.fraction = fraction;
    rc.topology = cluster::parse_topology(topology);
    rc.mode = cluster::parse_mode(mode);
    rc.chunks = static_cast<uint32_t>(chunks);
    rc.balance = balance == "on";
    rc.min_nodes = static_cast<uint32_t>(min_nodes);
    rc.timeout_s = timeout;
    rc.time_limit_s = time_limit;
    rc.target_error = target_error;
    rc.heartbeat_ms = static_cast<uint32_t>(heartbeat_ms);
    rc.liveness = static_cast<uint32_t>(liveness);
    if (!profile.empty()) rc.profile = emulation::load_profile(profile);
    rc.emulate_bandwidth = !network_bandwidth;
    std::optional<wire::Checkpoint> resumed;
    if (!resume.empty()) {
      // The run's settings are the checkpoint's: a flag that would change them is a mistake.
      for (const char* flag : {"--bundles", "--patches", "--grid", "--seed", "--rule", "--directions", "--control-variate",
                               "--shots-per-bundle", "--shot-resolution", "--exchange-every", "--exchange-fraction",
                               "--topology", "--mode", "--balance", "--chunks", "--time-limit", "--target-error"})
        if (app.count(flag) > 0) fail("{} with --resume: a resumed run keeps the checkpoint's settings", flag);
      resumed = cluster::read_checkpoint(resume);
      cluster::apply_checkpoint(rc, *resumed);  // the run's settings are the checkpoint's
      rc.resume = &*resumed;
      if (checkpoint.empty()) checkpoint = resume;
    }
    rc.checkpoint = checkpoint;
    rc.checkpoint_every_s = checkpoint_every;
    PatchMesh mesh = mesh_scene(rc.scene, rc.mesh_options);
    std::optional<Camera> given;
    if (!camera.empty()) {
      try {
        given = parse_camera(camera);
      } catch (const Error& e) {
        fail("--camera '{}': {}", camera, e.what());
      }
    }
    const SceneCheck check = check_scene(rc.scene, mesh, given);
    if (resumed && resumed->run().scene_hash() != mesh.hash)
      fail("{}: the checkpoint is of scene {}; {} meshes to {} (the same file, --patches and --two-sided?)", resume,
           resumed->run().scene_hash(), scene_spec, mesh.hash);
    for (const std::string& w : check.warnings) std::fprintf(stderr, "sirad-coordinator: warning: %s\n", w.c_str());
    proto::check_endpoint("--listen", listen, true);
    proto::check_security(listen, !curve_secret.empty(), insecure, "--curve-secret and --allow");
    std::optional<proto::KeyPair> keys;
    proto::AllowList allow;
    if (!curve_secret.empty()) {
      keys = proto::load_secret_key(curve_secret);
      allow = proto::load_allow_list(allow_file);
      if (allow.empty()) fail("{}: the allow list admits no node", allow_file);
    }
    if (check_config) {
      std::printf("sirad-coordinator: config ok: %s, %zu patches, %lld bundles, exchange every %s, S %g, %s, %s%s%s\n",
                  scene_spec.c_str(), mesh.size(), static_cast<long long>(bundles), exchange_every.c_str(), fraction,
                  topology.c_str(), mode.c_str(), profile.empty() ? "" : ", profile ", profile.c_str());
      return 0;
    }
    cluster::StatusReporter reporter(quiet, status_json);
    rc.status_every_s = 0.25;
    rc.status = std::ref(reporter);

    zmq::context_t context;
    std::optional<proto::ZapHandler> zap;  // before the bind: libzmq admits everyone without one
    if (keys) zap.emplace(context, allow);
    zmq::socket_t router(context, zmq::socket_type::router);
    router.set(zmq::sockopt::linger, 0);
    proto::harden(router, proto::max_frame_bytes(mesh.size()));
    if (keys) proto::make_curve_server(router, *keys);
    try {
      router.bind(listen);
    } catch (const zmq::error_t& e) {
      fail("--listen {}: {}", listen, e.what());
    }
    std::string bound = router.get(zmq::sockopt::last_endpoint);
    std::fprintf(stderr, "sirad-coordinator: %s: %zu patches, %lld bundles; listening on %s%s\n", scene_spec.c_str(),
                 mesh.size(), static_cast<long long>(bundles), bound.c_str(),
                 keys ? fmt::format(" (CURVE, {} node keys allowed)", allow.size()).c_str() : "");
    if (insecure) std::fprintf(stderr, "%s\n", proto::insecure_warning("sirad-coordinator", bound).c_str());
    if (!endpoint_file.empty()) {
      AtomicFile f(endpoint_file);
      f.write(bound.data(), bound.size());
      f.commit();
    }
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    rc.interrupt = &interrupted;
    auto start = std::chrono::steady_clock::now();
    cluster::RunResult result = cluster::coordinate(router, rc, mesh);
    reporter.finish();
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ResultOptions ro;
    ro.width = width;
    ro.height = height;
    ResultFiles files = write_results(out, mesh, result.radiosity, ro, cluster::run_attributes(rc, result, mesh, scene_spec));
    std::fputs(wrote_lines(files).c_str(), stdout);
    if (!ledger.empty()) {
      write_file_atomic(ledger, cluster::ledger_csv(result));
      std::printf("wrote %s\n", std::filesystem::absolute(ledger).c_str());
    }
    std::fputs(cluster::node_lines(result).c_str(), stdout);
    std::printf("%s\n", cluster::traffic_line(result).c_str());
    std::printf("patches %zu, bundles %lld, grid %d, nodes %zu, %.2f s, %.1f bundles/s, %.3g line crossings/s\n",
                mesh.size(), static_cast<long long>(result.bundles), result.grid, result.nodes.size(), seconds,
                result.bundles / seconds, static_cast<double>(result.crossings) / seconds);
    if (result.ended_by != "budget") std::printf("ended early: %s\n", result.ended_by.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad-coordinator: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
