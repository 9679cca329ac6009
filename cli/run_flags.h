// sirad: the flags that define a run, made from the table of a run's settings
// (cluster::setting_rows: each row's flag, help, default and parsing), and the output flags;
// shared by `sirad render`, `sirad emulate`, `sirad-coordinator` and the farm's job files (and by
// the coordinator's --resume, which refuses every run flag: a resumed run keeps its
// checkpoint's settings). The flags hold what was typed; settings_from turns them into the
// run's cluster::RunSettings, checked.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "cluster/settings.h"
#include "engine/bundle_cl.h"
#include "io/results.h"
#include "scene/mesh.h"
#include "scene/scene.h"

namespace sirad::cli {

// --target-error without --bundles: the cap it lifts the default of 1000 bundles to.
inline constexpr int64_t kTargetErrorCap = 1000000;

// The run flags as typed: each given flag's text, by its long name without "--" (the rows'
// `flag`); which were given is the command line's (given_flags).
struct RunFlags {
  std::map<std::string, std::string> text;
};

// A lightmap baked from the solution (render/bake.h; io/write_lightmap.h's files): `sirad bake`,
// or `sirad render --lightmap`.
struct LightmapFlags {
  bool on = false;
  double texel_size = 0;                 // --texel-size (0: from the budget)
  uint64_t texels = uint64_t{1} << 20;   // --texels: the budget
  int samples = 64;                      // --texel-samples
  int lights = 1;                        // --texel-lights: emitter samples per sample
  bool own_atlas = false;                // --own-atlas: sirad's charts even where the scene has TEXCOORD_1
};

struct OutputFlags {
  std::string out;
  int width = 0, height = 0;  // 0: settle_image_size gives them from the camera's aspect
  float exposure = 0.0f;
  bool flat = false;
  int final_gather_spp = 0;  // --final-gather: samples per pixel of a final gather image (0: the patches drawn)
  bool skip_degenerate = false;
  bool two_sided = false;
  bool outside_uris = false;  // --allow-outside-uris (ImportOptions::outside_uris)
  std::string camera;  // --camera "eye X Y Z look X Y Z up X Y Z fov DEG"
  LightmapFlags lightmap;  // not among add_output_flags' (a farm's job does not bake yet): add_lightmap_flags
  ImportOptions import() const { return {.skip_degenerate = skip_degenerate, .two_sided = two_sided, .outside_uris = outside_uris}; }
};

// The SCENE argument (a built-in name or a scene file).
void add_scene_argument(CLI::App* cmd, std::string& scene);
// The run flags, one per row of the table, the cluster's among them, or (`only`) those rows'
// alone; returns their long names ("--bundles", ...). Each flag's value is checked as it is
// parsed (its row's parse).
std::vector<std::string> add_run_flags(CLI::App* cmd, RunFlags& flags, const std::vector<std::string_view>& only = {});
// --transfer band|wide: the bundle engine's transfer path (engine/bundle_cl.h); unset, the
// device's own (band on a CPU, wide elsewhere; or SIRAD_PATH).
void add_transfer_flag(CLI::App* cmd, std::optional<TransferPath>& path);
// The rows of the meshing: what `sirad reference` and `sirad model --scene` take of a run's flags.
inline const std::vector<std::string_view> kMeshFlags = {"patches", "max-edge", "max-patches"};

// Number checks whose refusal reads plainly ("must be greater than 0 (got 0)"), for the flags
// CLI11's PositiveNumber and NonNegativeNumber would refuse with a 300-digit bound.
CLI::Validator positive();
CLI::Validator non_negative();
// A floating-point flag within [lo, hi]; NaN and infinities refused (CLI::Range lets NaN through).
CLI::Validator finite_in(double lo, double hi);
// The flags of the run flags that only a cluster uses (refused on one node).
const std::vector<std::string>& cluster_flag_names();
// Import and output: --out, --width, --height, --exposure, --flat, --final-gather,
// --skip-degenerate, --two-sided, --camera; returns their long names.
std::vector<std::string> add_output_flags(CLI::App* cmd, OutputFlags& flags);

// --texel-size, --texels and --texel-samples, and (`with_switch`) --lightmap to turn them on.
void add_lightmap_flags(CLI::App* cmd, LightmapFlags& flags, bool with_switch);
// `flags` (but --out) as the arguments that give them again through add_output_flags.
std::vector<std::string> output_args(const OutputFlags& flags);
// Sets `flags` from output_args' arguments (a checkpoint's); throws sirad::Error for ones that
// are not output flags.
void parse_output_args(const std::vector<std::string>& args, OutputFlags& flags, const std::string& origin);

// The long names of the options given on `cmd`'s command line.
std::set<std::string> given_flags(const CLI::App* cmd);

// The meshing the flags (kMeshFlags, `given` as given_flags says) ask for: --patches N,
// --max-edge L (not both), or about 10000 patches; --max-patches M. As settings_from makes it.
MeshOptions mesh_options_from(const RunFlags& flags, const std::set<std::string>& given);

// The run the flags ask for: every row's given text, else its default, in the table's order
// (`given`: the flags given; --patches and --max-edge exclude each other; --target-error without
// --bundles lifts the cap to kTargetErrorCap), checked (cluster::check). Throws sirad::Error
// naming the flag. With no flags: the command lines' defaults.
cluster::RunSettings settings_from(const RunFlags& flags, const std::set<std::string>& given);

// --camera's view, or none when it is empty; throws sirad::Error naming the flag.
std::optional<Camera> camera_flag(const std::string& camera);

// The images the output flags ask for: size, exposure, flat or Gouraud shading.
ResultOptions result_options(const OutputFlags& flags);
// The image size a run writes, once its scene is known: --width and --height as given; else the
// scene camera's aspect (glTF aspectRatio; 1 for other scenes, or with --camera) with a height
// of kDefaultImageHeight, or the side not given from the one given.
inline constexpr int kDefaultImageHeight = 512;
void settle_image_size(int& width, int& height, const std::optional<double>& aspect);
void settle_image_size(OutputFlags& flags, const Scene& scene);

}  // namespace sirad::cli
