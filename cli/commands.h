// sirad: what the subcommands of `sirad` do once cmd/sirad.cpp has parsed their flags: each
// takes its arguments and returns the process's exit status, or throws sirad::Error with the
// one line to print. render and emulate are in render_command.cpp, model in model_command.cpp,
// reference, image, devices and keygen in tool_commands.cpp; scene_outputs.h is what they share.
#pragma once
#include <cstdint>
#include <optional>
#include <set>
#include <string>

#include <CLI/CLI.hpp>

#include "cli/run_flags.h"
#include "model/model.h"
#include "render/gather.h"
#include "solver/reference.h"

namespace sirad::cli {

struct RenderArgs {
  std::string scene;
  RunFlags run;
  OutputFlags output;
  std::string device;
  std::optional<TransferPath> transfer;  // --transfer: the bundle engine's path (default: the device's)
  bool quiet = false;
  // The embedded cluster: N local nodes over ZeroMQ inproc (0: the plain single-node solver).
  int nodes = 0;
  std::string status_json;
  std::string profile;
  // --warm-start: a previous run's PLY whose solution this run starts from (solver/warm_start.h).
  std::string warm_start;
  std::set<std::string> given;  // the flags given on the command line (long names)
};

// `sirad render SCENE`: one node (the plain solver) or an embedded cluster of a.nodes.
int render(RenderArgs a);

struct EmulateArgs {
  RenderArgs run;
  double bundle_ms = 0;
  double tile_ms = 0;  // --tile-ms (0: measured)
  std::string nodes_csv, timeline;
};

// `sirad emulate`: the virtual-time cluster (cluster/emulate.h) on this machine's device.
int emulate(EmulateArgs& e);

// `sirad profile FILE`: the links a profile gives nodes 0..N-1 (named PREFIX0, PREFIX1, ...),
// one row each: for people checking a profile and for deploy/netns-cluster.sh.
int profile_table(const std::string& path, int nodes, const std::string& prefix);

// `sirad model`: the paper's cost and error model (model/model.h) for one setup, or swept over
// processors, exchange periods or fractions; CSV on stdout, then the exchange period that
// maximises the effective sample number.
struct ModelArgs {
  model::Setup setup;
  model::Costs costs;
  model::Scene scene_params;
  double time = 60.0;
  std::string sweep = "none";
  uint64_t max = 16;
  std::string scene;                // fit a, sigma_1 / C and T_i on this scene's real bundles
  RunFlags mesh;                    // its meshing (kMeshFlags)
  std::set<std::string> given;      // the flags given (given_flags)
  std::string device;
  std::string from_run;             // a --status-json file: P, I, S, T, T_i and T_e from a real run
  bool time_given = false;
  double time_to = 0;               // > 0: also the time the model needs to reach this error
  std::string profile;              // T_e from this profile's links for a state of state_patches
  std::optional<int64_t> state_patches;
  CLI::Option* t_exchange_flag = nullptr;
};

int model_table(ModelArgs m);

// `sirad reference SCENE`: the independent reference solver (solver/reference.h). Writes NAME.exr,
// .png, .ply like `render`, plus NAME.ref.csv (per-patch B, D and their standard errors).
struct ReferenceArgs {
  std::string scene;
  RunFlags mesh;                // the meshing (kMeshFlags)
  std::set<std::string> given;  // the flags given (given_flags)
  ReferenceOptions options;
  OutputFlags output;
  bool quiet = false;
};

int reference(const ReferenceArgs& r);

// sirad image SOLUTION: a final gather (render/gather.h) of a solution read back from the PLY or
// glTF sirad wrote (io/read_solution.h).
struct ImageArgs {
  std::string solution, camera, cameras, out;
  GatherOptions gather;
  float exposure = 0.0f;
  bool quiet = false;
};

int image(ImageArgs& a);

// `sirad devices`: the OpenCL devices, one a line.
int devices();

// sirad keygen NAME: a CURVE key pair (proto/security.h); the public key goes to the other side
// (a node's into the coordinator's allow list, the coordinator's to every node).
int keygen(const std::string& name);

}  // namespace sirad::cli
