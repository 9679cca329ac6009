// sirad-coordinator: serves one run of a scene to the nodes that connect, then writes its
// outputs (NAME.exr, NAME.png, NAME.ply, NAME.glb). The run flags are sirad render's
// (cli/run_flags.h); the rest are the coordinator's own: --listen, --min-nodes, security,
// liveness, checkpoints and --resume, status and ledger files. `sirad-coordinator --help`.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <set>

#include <CLI/CLI.hpp>

#include "cli/log_flags.h"
#include "cli/run_flags.h"
#include "cluster/checkpoint.h"
#include "cluster/live_view.h"
#include "cluster/policy.h"
#include "coordinator/coordinator.h"
#include "engine/bundle.h"
#include "engine/version.h"
#include "farm/farm.h"
#include "farm/farm_http.h"
#include "io/results.h"
#include "proto/security.h"
#include "proto/transport.h"
#include "scene/check.h"
#include "util/atomic_file.h"
#include "util/error.h"

using namespace sirad;

namespace {
std::atomic<bool> interrupted{false};
void on_signal(int) {
  interrupted = true;
}

// The ROUTER socket of a run or a farm: the ZAP handler first (libzmq admits everyone without
// one), frames bounded for `max_patches`, CURVE when `keys`, bound to `listen`; the bound
// endpoint logged and written to `endpoint_file`.
// --curve-secret and --allow (checked against --listen and --insecure first): the key pair and
// the admitted node keys, or none over inproc or with --insecure.
struct ServerKeys {
  std::optional<proto::KeyPair> keys;
  proto::AllowList allow;
};
ServerKeys server_keys(const std::string& listen, const std::string& curve_secret, const std::string& allow_file, bool insecure) {
  proto::check_endpoint("--listen", listen, true);
  proto::check_security(listen, !curve_secret.empty(), insecure, "--curve-secret and --allow");
  ServerKeys k;
  if (!curve_secret.empty()) {
    k.keys = proto::load_secret_key(curve_secret);
    k.allow = proto::load_allow_list(allow_file);
    if (k.allow.empty()) fail("{}: the allow list admits no node", allow_file);
  }
  return k;
}

struct Listener {
  std::optional<proto::ZapHandler> zap;
  zmq::socket_t router;
  std::optional<proto::PeerBytes> bytes;  // what libzmq holds per peer, bounded
  std::string bound;
  Listener(zmq::context_t& context, const std::string& listen, const std::optional<proto::KeyPair>& keys,
           const proto::AllowList& allow, std::size_t max_patches, bool insecure, const std::string& endpoint_file,
           const std::string& what) {
    if (keys) zap.emplace(context, allow);
    router = zmq::socket_t(context, zmq::socket_type::router);
    router.set(zmq::sockopt::linger, 0);
    proto::harden(router, proto::max_frame_bytes(max_patches));
    const uint64_t per_peer = proto::max_peer_bytes(max_patches);
    bytes.emplace(context, router, per_peer, [per_peer](const std::string& address, uint64_t held) {
      logging::write(logging::Level::warn, "sirad-coordinator",
                     fmt::format("{}: connection shut: libzmq held {} bytes of its unread messages, over the bound of {}", address,
                                 held, per_peer),
                     {{"event", "peer bytes"}, {"address", address}, {"held", held}});
    });
    if (keys) proto::make_curve_server(router, *keys);
    try {
      router.bind(listen);
    } catch (const zmq::error_t& e) {
      fail("--listen {}: {}", listen, e.what());
    }
    bound = router.get(zmq::sockopt::last_endpoint);
    logging::write(logging::Level::info, "sirad-coordinator",
                   fmt::format("{}; listening on {}{}", what, bound, keys ? fmt::format(" (CURVE, {} node keys allowed)", allow.size()) : ""),
                   {{"event", "listening"}, {"endpoint", bound}, {"version", kVersion}});
    if (insecure) logging::write(logging::Level::warn, "sirad-coordinator", proto::insecure_warning(bound), {{"event", "insecure"}});
    if (!endpoint_file.empty()) write_file_atomic(endpoint_file, bound);
  }
};
}  // namespace

// `--serve DIR`: the farm (farm/farm.h) on one socket, its HTTP API beside it, until SIGTERM.
int serve_farm(const std::string& dir, const std::string& http, const std::string& token_file, const std::string& listen,
               const std::string& endpoint_file, const std::string& curve_secret, const std::string& allow_file, bool insecure,
               bool check_config, uint32_t heartbeat_ms, uint32_t liveness, double checkpoint_every) {
  const auto [keys, allow] = server_keys(listen, curve_secret, allow_file, insecure);
  const auto colon = http.rfind(':');
  int port = -1;
  if (colon != std::string::npos && colon > 0 && colon + 1 < http.size() && colon + 6 >= http.size() &&
      std::all_of(http.begin() + static_cast<long>(colon) + 1, http.end(), [](char c) { return c >= '0' && c <= '9'; }))
    port = std::stoi(http.substr(colon + 1));
  if (port < 0 || port > 65535) fail("--http {}: expected HOST:PORT (e.g. 127.0.0.1:8080)", http);
  const std::string host = http.substr(0, colon);
  cluster::JobStore store(dir, cli::unix_now(), !check_config);  // a check changes nothing of a farm that may be running
  const std::string token = cli::farm_token(token_file.empty() ? (std::filesystem::path(dir) / "token").string() : token_file);
  if (check_config) {
    std::printf("sirad-coordinator: config ok: farm %s, %zu jobs, %s\n", dir.c_str(), store.list().size(), http.c_str());
    return 0;
  }
  zmq::context_t context;
  Listener listener(context, listen, keys, allow, cli::kFarmMaxPatches, insecure, endpoint_file, fmt::format("farm {}", dir));
  cli::FarmView view;
  cli::FarmHttp server(store, view, token);
  const int bound = server.start(host, port);
  const std::string url = fmt::format("http://{}:{}", host, bound);
  write_file_atomic((std::filesystem::path(dir) / "http").string(), url);
  logging::write(logging::Level::info, "sirad-coordinator", fmt::format("farm {}: web page and API on {}", dir, url),
                 {{"event", "http"}, {"url", url}});
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  cli::FarmOptions options;
  options.process.heartbeat_ms = heartbeat_ms;
  options.process.liveness = liveness;
  options.process.checkpoint_every_s = checkpoint_every;
  options.stop = &interrupted;
  options.peer_bytes = &*listener.bytes;
  cli::serve_farm(context, listener.router, store, options, view);
  server.stop();
  logging::write(logging::Level::info, "sirad-coordinator", "farm stopped", {{"event", "stopped"}});
  return 0;
}

int main(int argc, char** argv) {
  CLI::App app{"sirad-coordinator: orchestrates sirad nodes solving one scene"};
  app.set_version_flag("--version", [] { return sirad::version_text("sirad-coordinator"); }, "Version, git commit and OpenCL platforms");
  std::string scene_spec, listen = "tcp://*:5555", endpoint_file, status_json, profile, curve_secret, allow_file, ledger,
                          checkpoint, resume;
  cli::RunFlags run;
  cli::OutputFlags output;
  double checkpoint_every = 10, timeout = 0;
  int min_nodes = 1, heartbeat_ms = 1000, liveness = 3;
  bool check_config = false, quiet = false, network_bandwidth = false, insecure = false;
  cli::add_scene_argument(&app, scene_spec);
  app.get_option("scene")->required(false);  // --serve takes none; else checked below
  std::string serve, http = "127.0.0.1:8080", token_file;
  app.add_option("--serve", serve,
                 "Serve a farm: the job queue in this folder (made if need be), jobs side by side as their --max-nodes allow, until SIGTERM "
                 "(submit with sirad submit; jobs, progress and outputs over --http)");
  app.add_option("--http", http, "With --serve: the web page and JSON API's HOST:PORT (port 0: any free one)")->capture_default_str();
  app.add_option("--token-file", token_file,
                 "With --serve: the token submit and cancel need (mode 0600; default: DIR/token, made if missing)");
  app.add_option("--listen", listen, "ZeroMQ endpoint to bind")->capture_default_str();
  const std::vector<std::string> run_flags = cli::add_run_flags(&app, run);
  const std::vector<std::string> output_flags = cli::add_output_flags(&app, output);
  app.add_option("--min-nodes", min_nodes, "Nodes ready before the first grant")->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--endpoint-file", endpoint_file, "Write the bound endpoint here (for scripts: tcp://*:0 picks a port)");
  app.add_option("--status-json", status_json, "Rewrite this file with the run's status every second");
  app.add_option("--ledger", ledger, "At the end, write which node ran which bundle indices (CSV: node,name,first,last)");
  app.add_option("--timeout", timeout, "Fail if the run takes longer (seconds; 0: never)")->check(cli::non_negative());
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
      ->check(cli::finite_in(0.1, 86400.0))->capture_default_str();
  app.add_option("--resume", resume,
                 "Continue the run of this checkpoint (its settings; the same scene), checkpointing to it unless --checkpoint");
  app.add_flag("--check-config", check_config, "Check the flags, scene, profile and output place; run nothing");
  app.add_flag("-q,--quiet", quiet, "No progress view");
  cli::LogFlags log_flags;
  log_flags.add(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "sirad-coordinator: error: %s (see sirad-coordinator --help)\n", e.what());
    return 2;
  }
  try {
    log_flags.apply();
    const std::set<std::string> given = cli::given_flags(&app);
    if (!serve.empty()) {
      // A farm's runs take their flags from their jobs: these would have no effect.
      std::vector<std::string> per_job = run_flags;
      per_job.insert(per_job.end(), output_flags.begin(), output_flags.end());
      for (const char* f : {"--resume", "--checkpoint", "--status-json", "--ledger", "--min-nodes", "--timeout", "--profile",
                            "--bandwidth-by-network"})
        per_job.push_back(f);
      for (const std::string& f : per_job)
        if (given.count(f)) fail("{} with --serve: each job gives its own (sirad submit SCENE {} ...)", f, f);
      if (!scene_spec.empty()) fail("--serve takes no scene: submit jobs (sirad submit {})", scene_spec);
      return serve_farm(serve, http, token_file, listen, endpoint_file, curve_secret, allow_file, insecure, check_config,
                        static_cast<uint32_t>(heartbeat_ms), static_cast<uint32_t>(liveness), checkpoint_every);
    }
    if (given.count("--http") || given.count("--token-file")) fail("--http and --token-file: only with --serve");
    if (scene_spec.empty()) fail("a scene is required (or --serve DIR)");
    std::string out = output.out.empty() ? std::filesystem::path(scene_spec).stem().string() : output.out;
    check_output_name(out, "--out");
    if (!ledger.empty()) check_file_name(ledger, "--ledger");
    if (!checkpoint.empty()) check_file_name(checkpoint, "--checkpoint");
    if (!status_json.empty()) check_file_name(status_json, "--status-json");
    cluster::RunConfig rc;
    std::optional<wire::Checkpoint> resumed;
    if (!resume.empty()) {
      // The run's settings are the checkpoint's: a flag that would change them is a mistake.
      for (const std::string& flag : run_flags)
        if (given.count(flag)) fail("{} with --resume: a resumed run keeps the checkpoint's settings", flag);
      resumed = cluster::read_checkpoint(resume);
      static_cast<cluster::RunSettings&>(rc) = cluster::settings_of(*resumed);
      rc.resume = &*resumed;
      if (checkpoint.empty()) checkpoint = resume;
      // The outputs the run was started for, unless this command names its own.
      const bool outputs_given = std::any_of(output_flags.begin(), output_flags.end(),
                                             [&](const std::string& f) { return f != "--out" && given.count(f); });
      if (!outputs_given)
        cli::parse_output_args({resumed->output_args().begin(), resumed->output_args().end()}, output, resume);
    } else {
      static_cast<cluster::RunSettings&>(rc) = cli::settings_from(run, given);
      if (std::string why = cluster::target_error_problem(rc); !why.empty()) fail("{}", why);
    }
    rc.scene = load_scene(scene_spec, output.import());
    cli::settle_image_size(output, rc.scene);
    rc.min_nodes = static_cast<uint32_t>(min_nodes);
    rc.timeout_s = timeout;
    rc.heartbeat_ms = static_cast<uint32_t>(heartbeat_ms);
    rc.liveness = static_cast<uint32_t>(liveness);
    if (!profile.empty()) rc.profile = emulation::load_profile(profile);
    cluster::check_real_run(rc);
    rc.emulate_bandwidth = !network_bandwidth;
    rc.checkpoint = checkpoint;
    rc.checkpoint_every_s = checkpoint_every;
    rc.output_args = cli::output_args(output);
    PatchMesh mesh = mesh_scene(rc.scene, rc.mesh_options);
    const SceneCheck check = check_scene(rc.scene, mesh, cli::camera_flag(output.camera), "--camera");
    if (resumed && resumed->run().scene_hash() != mesh.hash)
      fail("{}: the checkpoint is of scene {}; {} meshes to {} (the same file, --patches and --two-sided?)", resume,
           resumed->run().scene_hash(), scene_spec, mesh.hash);
    for (const std::string& w : check.warnings) std::fprintf(stderr, "sirad-coordinator: warning: %s\n", w.c_str());
    const auto [keys, allow] = server_keys(listen, curve_secret, allow_file, insecure);
    if (check_config) {
      std::printf("sirad-coordinator: config ok: %s, %zu patches, %lld bundles, exchange every %s, S %g, %s, %s%s%s\n",
                  scene_spec.c_str(), mesh.size(), static_cast<long long>(rc.bundles), cluster::exchange_every_name(rc.exchange_every).c_str(),
                  rc.fraction, rc.topology == cluster::Topology::star ? "star" : "ring", rc.mode == cluster::Mode::sync ? "sync" : "async",
                  profile.empty() ? "" : ", profile ", profile.c_str());
      return 0;
    }
    cluster::StatusReporter reporter(quiet, status_json);
    rc.status_every_s = 0.25;
    const ResultOptions shown = cli::result_options(output);
    rc.final_gather = final_gather_of(shown);  // the image's tiles rendered by the nodes
    rc.status = std::ref(reporter);

    zmq::context_t context;
    Listener listener(context, listen, keys, allow, mesh.size(), insecure, endpoint_file,
                      fmt::format("{}: {} patches, {} bundles", scene_spec, mesh.size(), rc.bundles));
    zmq::socket_t& router = listener.router;
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    rc.interrupt = &interrupted;
    auto start = std::chrono::steady_clock::now();
    cluster::RunResult result = cluster::coordinate(router, rc, mesh, &*listener.bytes);
    reporter.finish();
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!ledger.empty()) {  // first: the ledger stays with the solution should the image have failed
      write_file_atomic(ledger, cluster::ledger_csv(result));
      std::printf("wrote %s\n", std::filesystem::absolute(ledger).c_str());
    }
    ResultFiles files = write_results(
        out, mesh, result.radiosity, shown, cluster::run_attributes(rc, cluster::outcome_of(result), mesh, scene_spec, true),
        result.image ? &*result.image : nullptr, result.image_error);
    std::fputs(wrote_lines(files).c_str(), stdout);
    std::fputs(cluster::cluster_summary(result, mesh.size(), seconds).c_str(), stdout);
    if (result.ended_by != "budget") std::printf("ended early: %s\n", result.ended_by.c_str());
    if (result.bundles_lost) {  // the outputs are written: the run is not what was asked
      std::fprintf(stderr, "sirad-coordinator: error: %s\n", cluster::Policy::lost_reason(*result.bundles_lost).c_str());
      return 1;
    }
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "sirad-coordinator: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad-coordinator: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
