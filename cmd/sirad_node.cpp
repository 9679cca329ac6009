// sirad-node: a worker that serves runs from a coordinator until stopped (SIGINT/SIGTERM).
//   sirad-node --connect tcp://HOST:5555 [--device D] [--name NAME] [--check-config]
//     [--curve-secret FILE --server-key FILE | --insecure]   (one of them over tcp://)
//     [--scene-cache DIR] [--max-patches N]
#include <atomic>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <unistd.h>

#include "cli/log_flags.h"
#include "cli/program.h"
#include "cli/run_flags.h"
#include "cli/stop_signals.h"
#include "engine/opencl.h"
#include "engine/version.h"
#include "node/node.h"
#include "node/scene_cache.h"
#include "proto/transport.h"
#include "util/error.h"
#include "util/log.h"

int main(int argc, char** argv) {
  CLI::App app{"sirad-node: runs bundles for a sirad coordinator"};
  app.set_version_flag("--version", [] { return sirad::version_text("sirad-node"); }, "Version, git commit and OpenCL platforms");
  std::string endpoint, device;
  char host[256] = "node";
  ::gethostname(host, sizeof(host) - 1);
  std::string name = host;
  sirad::node::NodeOptions options;
  app.add_option("--connect", endpoint, "Coordinator endpoint, e.g. tcp://host:5555")->required();
  app.add_option("--device", device, "OpenCL device: P:D or part of its name (env SIRAD_DEVICE)");
  sirad::cli::add_transfer_flag(&app, options.transfer);
  app.add_option("--name", name, "Name shown by the coordinator")->capture_default_str();
  app.add_option("--max-patches", options.max_patches, "Refuse runs of more patches (bounds this node's memory and largest message)")
      ->check(CLI::Range(uint32_t{1}, uint32_t{1} << 31))
      ->capture_default_str();
  app.add_option("--scene-cache", options.scene_cache,
                 "Keep the scenes this node is sent in this folder (named by their hash), so a restarted node is not sent them again");
  app.add_option("--threads", options.gather_threads, "Threads that render a final gather's tiles (0: every core)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  std::string curve_secret, server_key;
  bool check_config = false, insecure = false;
  auto* secret_opt = app.add_option("--curve-secret", curve_secret, "This node's CURVE secret key file (NAME.key_secret from sirad keygen; mode 0600)");
  auto* server_opt = app.add_option("--server-key", server_key, "The coordinator's CURVE public key file (its NAME.key)");
  secret_opt->needs(server_opt);
  server_opt->needs(secret_opt);
  app.add_flag("--insecure", insecure, "Over TCP without CURVE: no authentication, no encryption (says so on start)");
  app.add_flag("--check-config", check_config, "Check the flags, keys and the OpenCL device; connect to nothing");
  sirad::cli::LogFlags log_flags;
  log_flags.add(app);
  if (std::optional<int> exit = sirad::cli::parse_command_line(app, argc, argv, "sirad-node")) return *exit;
  constexpr int kServe = -1;  // the flags are good and --check-config not given: serve
  const int checked = sirad::cli::guarded("sirad-node", [&] {
    log_flags.apply();
    sirad::proto::check_endpoint("--connect", endpoint, false);
    sirad::proto::check_security(endpoint, !curve_secret.empty(), insecure, "--curve-secret and --server-key");
    if (!curve_secret.empty()) {
      options.curve_keys = sirad::proto::load_secret_key(curve_secret);
      options.server_key = sirad::proto::load_public_key(server_key);
    }
    if (!options.scene_cache.empty()) sirad::node::SceneCache check(options.scene_cache);  // a folder, or one is made
    if (check_config) {
      sirad::DeviceInfo d = sirad::describe_device(sirad::select_device(device));
      std::printf("sirad-node: config ok: %s -> %s, device %s / %s\n", name.c_str(), endpoint.c_str(),
                  d.platform_name.c_str(), d.device_name.c_str());
      return 0;
    }
    return kServe;
  });
  if (checked != kServe) return checked;
  const std::atomic<bool>& stop = sirad::cli::stop_on_signals();
  if (insecure)
    sirad::logging::write(sirad::logging::Level::warn, "sirad-node", sirad::proto::insecure_warning(endpoint), {{"event", "insecure"}});
  options.name = name;
  options.device = device;
  options.stop = &stop;
  return sirad::cli::guarded("sirad-node", [&] {
    zmq::context_t context;
    sirad::node::serve(context, endpoint, options);
    if (stop) sirad::logging::write(sirad::logging::Level::info, "sirad-node " + name, "stopped by a signal; leaving",
                                    {{"event", "left"}, {"why", "signal"}, {"node", name}});
    return 0;
  });
}
