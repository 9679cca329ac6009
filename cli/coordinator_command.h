// sirad: `sirad-coordinator SCENE`: one run served to the nodes that connect, its outputs
// written at the end (NAME.exr, .png, .ply, .glb, and the ledger and status files asked for).
// cmd/sirad_coordinator.cpp parses the flags into CoordinatorArgs; the farm (--serve) is
// farm/farm_command.h.
#pragma once
#include <set>
#include <string>
#include <vector>

#include "cli/run_flags.h"

namespace sirad::cli {

// sirad-coordinator's flags as given.
struct CoordinatorArgs {
  std::string scene, listen = "tcp://*:5555", endpoint_file, status_json, profile, curve_secret, allow_file, ledger, checkpoint,
                     resume;
  RunFlags run;
  OutputFlags output;
  double checkpoint_every = 10, timeout = 0;
  int min_nodes = 1, heartbeat_ms = 1000, liveness = 3;
  bool check_config = false, quiet = false, network_bandwidth = false, insecure = false;
  std::vector<std::string> run_flags, output_flags;  // their long names (add_run_flags, add_output_flags)
  std::set<std::string> given;                       // the flags given (given_flags)
};

// One run of a.scene (or of the checkpoint a.resume names); with a.check_config the flags,
// scene, profile and output place checked and nothing run. The exit status: 1 when bundles
// were lost (the outputs are written), else 0; throws sirad::Error for bad input.
int coordinate_command(CoordinatorArgs a);

}  // namespace sirad::cli
