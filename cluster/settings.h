// sirad: what defines a run (RunSettings), with its one validation and its conversions: to and
// from the wire (the Run of WELCOME and of the checkpoint), to a node's solver options, to the
// policy's configuration, and to the EXR header attributes. Every driver, `sirad render` on one
// node or many, `sirad emulate`, `sirad-coordinator` and `sirad-node`, holds a run's settings
// in this one type; the command lines fill it from one declaration of the flags (cli/run_flags.h).
// The settings of a process (timeouts, heartbeats, files) and the hooks a driver gives a run
// (signals, callbacks) are kept apart from it, in ProcessSettings and RunHooks.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cluster/deadlines.h"
#include "cluster/exchange.h"
#include "cluster/profile.h"
#include "engine/bundle.h"
#include "io/write.h"
#include "proto/codec.h"
#include "render/gather.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/solver.h"

namespace sirad::cluster {

struct Status;
struct PolicyConfig;
struct ExchangeSetting;
class Policy;

// What defines a run: with the scene, its result is a function of these and of which node ran
// which bundle. The defaults are the library's (plain runs in tests and benches); the command
// lines' defaults are their flags' (cli/run_flags.h).
struct RunSettings {
  MeshOptions mesh_options;     // how the nodes mesh the scene
  uint64_t bundles = 1000;      // K: the budget (the cap when a time limit or target ends it early)
  uint64_t seed = 1;
  int grid = 0;                 // lines per side (0: auto from the mesh)
  UpdateRule rule = UpdateRule::chain;
  int burn_in = -1;             // chain bundles run before counting (-1: auto)
  Directions directions = Directions::random;  // stratified: chain rule only
  bool control_variate = true;  // the transport's control variate (solver/solver.h SolverOptions)
  double shots_per_bundle = 0;  // first shot: shots rendered per bundle (0: off)
  int shot_resolution = 0;      // hemicube side (0: auto)
  uint32_t exchange_every = 0;  // I; 0: states only at the end; kExchangeAuto: chosen at the start
  double fraction = 1.0;        // S
  Topology topology = Topology::star;
  Mode mode = Mode::async;
  uint32_t chunks = 16;
  bool balance = true;          // grants sized to each node's speed (PolicyConfig::balance)
  double time_limit_s = 0;      // 0: none; else no grants after this long: the run ends early
  double target_error = 0;      // 0: none; else the run ends once the error estimate is at or below it
};

// The bounds of every run's settings, whoever gives them (a flag, a WELCOME, a checkpoint):
// far beyond what a run needs, and what the engines and the policy are sized for, so no
// message or file can make a process allocate or loop beyond them.
inline constexpr int kMaxGrid = 8192;                   // lines per side: 67 M lines a bundle
inline constexpr int kMaxBurnIn = 1 << 20;              // bundles
inline constexpr uint64_t kMaxBundles = uint64_t{1} << 40;
inline constexpr uint64_t kMaxTargetPatches = uint64_t{1} << 31;
inline constexpr double kMaxSeconds = 1e9;              // a time limit or a run's elapsed time (31 years)

// One row of the table of a run's settings (settings.cpp): what is said about a setting, in one
// place, from which the command lines' flags (cli/run_flags.cpp), check(), the wire (to_wire,
// from_wire) and the checkpoint (put_settings, settings_of) are made. A new setting is its
// RunSettings member, its row (and its field in proto/sirad.proto when the nodes need it), and
// the code that uses it.
struct SettingRow {
  std::string_view flag;                  // the long flag without "--" ("bundles")
  std::string_view help;
  std::string_view type;                  // what --help says it takes: INT, FLOAT, the names, ...
  std::vector<std::string_view> choices;  // the names it takes, for --help (none: a number)
  std::string_view default_text;          // the command lines' default ("": RunSettings' stands: auto, none)
  bool show_default = false;              // --help shows it
  bool cluster = false;                   // a cluster's only: refused on one node
  // Sets the setting from the flag's text; the rows before it are set (--directions auto
  // follows --rule). Throws sirad::Error saying what is wrong (the caller names the flag).
  void (*parse)(RunSettings& s, const std::string& text) = nullptr;
  // Throws sirad::Error, naming the setting, for a value no run can have, whoever gave it.
  void (*check)(const RunSettings& s) = nullptr;
  // The setting onto and from the wire's Run (WELCOME, and the checkpoint's run), or, for the
  // coordinator's own, the checkpoint's fields (null where it has none of them).
  void (*to_run)(const RunSettings& s, const PatchMesh& mesh, wire::Run& r) = nullptr;
  void (*from_run)(const wire::Run& r, RunSettings& s) = nullptr;
  void (*to_checkpoint)(const RunSettings& s, wire::Checkpoint& c) = nullptr;
  void (*from_checkpoint)(const wire::Checkpoint& c, RunSettings& s) = nullptr;
  // The setting as its flag's text, which `parse` reads back to the same value; "" where the
  // setting holds its own default (auto, none), which a flag does not spell.
  std::string (*text)(const RunSettings& s) = nullptr;
};
// The rows, in the order the flags are parsed (and listed by --help).
const std::vector<SettingRow>& setting_rows();

// A run's settings as their flags' text, (flag, text) in the table's order, the rows whose text
// is "" left out: what the farm's job files and the status hold. settings_from_text reads it
// back, every row in the table's order whatever the order given, a row not given left at
// RunSettings' default (the "" of its text), and checks it (check()): settings_from_text(
// settings_text(s)) is s. Throws sirad::Error naming `origin` and the flag for a flag that is
// not a row's, one given twice, or a text its row refuses.
using SettingsText = std::vector<std::pair<std::string, std::string>>;
SettingsText settings_text(const RunSettings& s);
RunSettings settings_from_text(const SettingsText& text, const std::string& origin);

// Throws sirad::Error, naming the setting, for settings no run can have (each row's check):
// stratified directions under the average rule, a first shot out of range (check_first_shot),
// bundles outside [1, kMaxBundles], a grid or burn-in beyond its bound, a fraction outside
// (0, 1], chunks outside [1, kMaxChunks], a time limit outside [0, kMaxSeconds], a target
// outside [0, 1], or meshing options no mesh can have.
void check(const RunSettings& s);

// The grid the run uses on `mesh`: s.grid, or auto_grid(mesh) where it is 0.
// Why a cluster run of `s` cannot end at its target error (empty: it can). Under the chain rule
// the estimate combines the nodes' own batch means, reported with every grant, so any exchange
// setting works; under the average rule it is the spread of the nodes' exchanged states, which
// an exchange only at the end does not give.
std::string target_error_problem(const RunSettings& s);

int run_grid(const RunSettings& s, const PatchMesh& mesh);

// The wire Run of `s` on `mesh` (scene hash, grid as resolved, chunk starts, patches); the
// run id is the coordinator's to set. And back: the settings a Run carries (a node's WELCOME,
// a checkpoint), checked as check() does and for the Run's own shape: a rule, directions,
// topology or mode it does not know, no patches, or chunk starts that do not begin at 0 and
// rise strictly below the patch count throw sirad::Error. balance, time_limit_s and
// target_error are the coordinator's alone: not on the wire.
wire::Run to_wire(const RunSettings& s, const PatchMesh& mesh, const std::vector<uint32_t>& chunk_starts);
RunSettings from_wire(const wire::Run& run);

// The settings of a checkpointed run (its Run and the coordinator's own three), and into a
// checkpoint: a resumed run is the same run.
RunSettings settings_of(const wire::Checkpoint& c);
void put_settings(wire::Checkpoint& c, const RunSettings& s, const wire::Run& run);

// The solver options of the chain `chain_id` (a node's index in the run) on `mesh`: its batch
// means go out with each REPORT under the chain rule (memory-bounded: error_estimate.h).
SolverOptions solver_options(const RunSettings& s, const PatchMesh& mesh, uint64_t chain_id);

// The policy's configuration for a run of `s` on `mesh` that waits for `min_nodes` (checks the
// settings; the chooser of --exchange-every auto is the driver's to add).
PolicyConfig policy_config(const RunSettings& s, const PatchMesh& mesh, uint32_t min_nodes);

// The policy of a run of `s` on `mesh` (its chunks and error weights), as every cluster driver
// makes it; with --exchange-every auto, `choose` is the driver's measurement of its nodes.
Policy make_policy(const RunSettings& s, const PatchMesh& mesh, uint32_t min_nodes,
                   std::function<ExchangeSetting(const std::vector<uint32_t>& ready)> choose);

// How a run came out, for its attributes and summary line.
struct RunOutcome {
  uint64_t bundles = 0;         // counted bundles done
  int grid = 0;                 // as run
  uint32_t nodes = 1;
  uint32_t exchange_every = 0;  // as in force (what auto chose)
  double fraction = 1.0;
  std::string ended_by;         // "budget", "time limit", ... as the EXR says it
  double seconds = 0;           // the run's time (0: unknown; then no rates are written)
  uint64_t crossings = 0;       // line-patch crossings of the counted bundles
};

// The EXR header attributes of a run (DESIGN.md section 4: version, scene as the user named it,
// scene hash, patches, bundles, grid, seed, rule, directions, control variate, first shot,
// nodes, I, S, how it ended; the topology and mode of a cluster; its time and rates: bundles,
// patch-bundles and line crossings per second), one writer for every driver.
// `cluster`: a run of the cluster's drivers (their topology and mode are part of it).
Attributes run_attributes(const RunSettings& s, const RunOutcome& outcome, const PatchMesh& mesh, const std::string& scene,
                          bool cluster);

// What a driver gives a run besides its settings: the scene and the emulation that shapes it.
// Process settings: how long it may take and how its peers are watched, and where it writes.
struct ProcessSettings {
  uint32_t min_nodes = 1;       // nodes ready before the first grant
  double timeout_s = 0;         // 0: none; else the run fails if it takes longer
  uint32_t heartbeat_ms = 1000; // HEARTBEAT interval of both sides (PROTOCOL.md section 4)
  uint32_t liveness = 3;        // a peer silent this many intervals is dead
  // When a node's grants (of bundles or tiles) are due (cluster/deadlines.h); the slack is at
  // least the liveness window (grant_deadlines).
  DeadlineRules deadlines;
  std::optional<emulation::Profile> profile;  // network and speed emulation
  bool emulate_bandwidth = true;  // false: the network itself limits bandwidth (tc tbf in the
                                  // namespace cluster); the profile's other settings still apply
  bool strict = false;          // a node's ERROR ends the run (the embedded driver's: its nodes
                                // are this process's own threads)
  // The checkpoint (cluster/checkpoint.h): written atomically every checkpoint_every_s and
  // when `interrupt` is set ("": none).
  std::string checkpoint;
  double checkpoint_every_s = 10;
  double status_every_s = 1.0;  // how often RunHooks::status is called
  // The run's image by a final gather (render/gather.h) of the mesh's camera: spp > 0 renders it
  // after the solve, in tiles by the nodes that sent their FINAL (PROTOCOL.md section 3.4),
  // into RunResult::image; spp 0: none (the driver draws the patches).
  GatherOptions final_gather{.spp = 0};
  // The driver's output flags, kept in each checkpoint (wire::Checkpoint::output_args) so that a
  // resume without them renders the outputs the run was started for.
  std::vector<std::string> output_args;
};

// The rules of grants' due times a coordinator keeps: `p.deadlines`, its slack at least the
// liveness window (heartbeat_ms x liveness).
DeadlineRules grant_deadlines(const ProcessSettings& p);

// Who a peer is to a coordinator: its CURVE public key ("" without CURVE) and IP address ("" off tcp://).
struct PeerIdentity {
  std::string key, address;
};

// The hooks a driver gives a run: signals it watches and callbacks it is given.
struct RunHooks {
  const std::atomic<bool>* abort = nullptr;      // set: the run fails at once (a local node died)
  const std::atomic<bool>* interrupt = nullptr;  // set (SIGTERM): checkpoint, then the run throws
  // set (SIGINT on `sirad render --nodes`): the run closes as at a time limit, ended by
  // "interrupted": no more grants, the outstanding ones finish, the result is what was done.
  const std::atomic<bool>* close = nullptr;
  // Continue this checkpointed run (read_checkpoint; settings_of gave the settings): its nodes'
  // states and the ledger as accepted, the rest of the budget to run.
  const wire::Checkpoint* resume = nullptr;
  std::function<void(uint64_t done, uint64_t total)> progress;  // called as bundles complete
  std::function<void(const Status&)> status;  // called every status_every_s, and at the end
  // The estimate so far (count-weighted over the states the nodes have sent: zeros where none
  // came yet), every preview_every_s once there is one (a farm's preview image of a running job).
  std::function<void(const std::vector<glm::vec3>& radiosity)> preview;
  double preview_every_s = 2.0;
  // A broker's run (the farm's jobs, on a socket of their own behind its endpoint): the CURVE
  // key and IP address behind a routing id, which the broker saw on its socket (the messages
  // that reach this run's socket carry neither).
  std::function<PeerIdentity(const std::string& id)> peer_identity;
};

// A run as a cluster driver is given it.
struct RunConfig : RunSettings, ProcessSettings, RunHooks {
  Scene scene;  // sent to the nodes, which mesh it with `mesh_options`
};

}  // namespace sirad::cluster
