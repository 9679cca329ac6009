// sirad-coordinator: serves one run of a scene to the nodes that connect, then writes its
// outputs (NAME.exr, NAME.png, NAME.ply, NAME.glb); with --serve DIR, a farm. The run flags are
// sirad render's (cli/run_flags.h); the rest are the coordinator's own: --listen, --min-nodes,
// security, liveness, checkpoints and --resume, status and ledger files. This file declares the
// flags and hands them on: one run to cli/coordinator_command.h, a farm to farm/farm_command.h.
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli/coordinator_command.h"
#include "cli/log_flags.h"
#include "cli/program.h"
#include "cli/run_flags.h"
#include "engine/version.h"
#include "farm/farm_command.h"
#include "util/error.h"

using namespace sirad;

int main(int argc, char** argv) {
  CLI::App app{"sirad-coordinator: orchestrates sirad nodes solving one scene"};
  app.set_version_flag("--version", [] { return sirad::version_text("sirad-coordinator"); }, "Version, git commit and OpenCL platforms");
  cli::CoordinatorArgs a;
  cli::add_scene_argument(&app, a.scene);
  app.get_option("scene")->required(false);  // --serve takes none; else checked below
  std::string serve, http = "127.0.0.1:8080", token_file;
  app.add_option("--serve", serve,
                 "Serve a farm: the job queue in this folder (made if need be), jobs side by side as their --max-nodes allow, until SIGTERM "
                 "(submit with sirad submit; jobs, progress and outputs over --http)");
  app.add_option("--http", http, "With --serve: the web page and JSON API's HOST:PORT (port 0: any free one)")->capture_default_str();
  app.add_option("--token-file", token_file,
                 "With --serve: the token submit and cancel need (mode 0600; default: DIR/token, made if missing)");
  app.add_option("--listen", a.listen, "ZeroMQ endpoint to bind")->capture_default_str();
  a.run_flags = cli::add_run_flags(&app, a.run);
  a.output_flags = cli::add_output_flags(&app, a.output);
  app.add_option("--min-nodes", a.min_nodes, "Nodes ready before the first grant")->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--endpoint-file", a.endpoint_file, "Write the bound endpoint here (for scripts: tcp://*:0 picks a port)");
  app.add_option("--status-json", a.status_json, "Rewrite this file with the run's status every second");
  app.add_option("--ledger", a.ledger, "At the end, write which node ran which bundle indices (CSV: node,name,first,last)");
  app.add_option("--timeout", a.timeout, "Fail if the run takes longer (seconds; 0: never)")->check(cli::non_negative());
  app.add_option("--profile", a.profile, "Network emulation profile (YAML; see deploy/profiles/)");
  app.add_option("--heartbeat-ms", a.heartbeat_ms, "Heartbeat interval")->check(CLI::Range(10, 60000))->capture_default_str();
  app.add_option("--liveness", a.liveness, "Heartbeats a node may miss before it is dead")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_flag("--bandwidth-by-network", a.network_bandwidth,
               "The network limits bandwidth (tc); do not emulate the profile's up/down rates");
  auto* secret_opt = app.add_option("--curve-secret", a.curve_secret,
                                    "This coordinator's CURVE secret key file (NAME.key_secret from sirad keygen; mode 0600)");
  auto* allow_opt = app.add_option("--allow", a.allow_file, "Allow list: the node public keys admitted, one Z85 key (and a name) per line");
  secret_opt->needs(allow_opt);
  allow_opt->needs(secret_opt);
  app.add_flag("--insecure", a.insecure, "Over TCP without CURVE: no authentication, no encryption (says so on start)");
  app.add_option("--checkpoint", a.checkpoint,
                 "Write the run's checkpoint here (atomically) every --checkpoint-every seconds and on SIGTERM/SIGINT");
  app.add_option("--checkpoint-every", a.checkpoint_every, "Seconds between checkpoints")
      ->check(cli::finite_in(0.1, 86400.0))->capture_default_str();
  app.add_option("--resume", a.resume,
                 "Continue the run of this checkpoint (its settings; the same scene), checkpointing to it unless --checkpoint");
  app.add_flag("--check-config", a.check_config, "Check the flags, scene, profile and output place; run nothing");
  app.add_flag("-q,--quiet", a.quiet, "No progress view");
  cli::LogFlags log_flags;
  log_flags.add(app);
  if (std::optional<int> exit = cli::parse_command_line(app, argc, argv, "sirad-coordinator")) return *exit;
  return cli::guarded("sirad-coordinator", [&] {
    log_flags.apply();
    a.given = cli::given_flags(&app);
    if (!serve.empty()) {
      // A farm's runs take their flags from their jobs: these would have no effect.
      std::vector<std::string> per_job = a.run_flags;
      per_job.insert(per_job.end(), a.output_flags.begin(), a.output_flags.end());
      for (const char* f : {"--resume", "--checkpoint", "--status-json", "--ledger", "--min-nodes", "--timeout", "--profile",
                            "--bandwidth-by-network"})
        per_job.push_back(f);
      for (const std::string& f : per_job)
        if (a.given.count(f)) fail("{} with --serve: each job gives its own (sirad submit SCENE {} ...)", f, f);
      if (!a.scene.empty()) fail("--serve takes no scene: submit jobs (sirad submit {})", a.scene);
      return cli::serve_farm_command(a, serve, http, token_file);
    }
    if (a.given.count("--http") || a.given.count("--token-file")) fail("--http and --token-file: only with --serve");
    return cli::coordinate_command(std::move(a));
  });
}
