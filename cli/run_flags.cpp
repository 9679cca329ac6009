// sirad: the run and output flags (see run_flags.h).
#include "cli/run_flags.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "cluster/exchange.h"
#include "util/error.h"
#include "util/numbers.h"

namespace sirad::cli {

void add_scene_argument(CLI::App* cmd, std::string& scene) {
  cmd->add_option("scene", scene,
                  "Built-in scene (cornell, furnace, bright-room, three-lights) or a scene file (.obj, .gltf, .glb, .ply)")
      ->required();
}

namespace {

// A check of a flag's text by `read`, whose sirad::Error is the refusal CLI11 prints after the
// flag's name (util/numbers.h, a settings row's parse).
CLI::Validator reads_as(std::function<void(const std::string&)> read, const std::string& description) {
  return CLI::Validator(
      [read = std::move(read)](std::string& text) -> std::string {
        try {
          read(text);
        } catch (const Error& e) {
          return e.what();
        }
        return "";
      },
      description);
}

}  // namespace

CLI::Validator positive() { return reads_as([](const std::string& t) { positive_real(t); }, "POSITIVE"); }
CLI::Validator non_negative() { return reads_as([](const std::string& t) { non_negative_real(t); }, "NONNEGATIVE"); }
CLI::Validator finite_in(double lo, double hi) {
  return reads_as([lo, hi](const std::string& t) { real_in(t, lo, hi); }, fmt::format("[{}, {}]", lo, hi));
}

void add_transfer_flag(CLI::App* cmd, std::optional<TransferPath>& path) {
  cmd->add_option_function<std::string>(
         "--transfer", [&path](const std::string& name) { path = parse_transfer_path(name); },
         "Bundle transfer path: band (one work-item per band of rows: CPUs) or wide (one per patch, span or line: GPUs); "
         "default: the device's (env SIRAD_PATH)")
      ->check(CLI::IsMember({"band", "wide"}))
      ->type_name("band|wide");
}

std::vector<std::string> add_run_flags(CLI::App* cmd, RunFlags& r, const std::vector<std::string_view>& only) {
  std::vector<std::string> names;
  for (const cluster::SettingRow& row : cluster::setting_rows()) {
    if (!only.empty() && std::find(only.begin(), only.end(), row.flag) == only.end()) continue;
    const std::string flag(row.flag);
    CLI::Option* o = cmd->add_option("--" + flag, r.text[flag], std::string(row.help));
    // Its row's parse on the defaults: the value's own bounds (--directions stratified under
    // --rule average is settings_from's, where the rule is known).
    o->check(reads_as(
        [&row](const std::string& text) {
          cluster::RunSettings scratch;
          row.parse(scratch, text);
        },
        row.choices.empty() ? "" : fmt::format("{{{}}}", fmt::join(row.choices, ","))));
    o->type_name(std::string(row.type));
    if (row.show_default) o->default_str(std::string(row.default_text));
    names.push_back("--" + flag);
  }
  return names;
}

const std::vector<std::string>& cluster_flag_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const cluster::SettingRow& row : cluster::setting_rows())
      if (row.cluster) out.push_back("--" + std::string(row.flag));
    return out;
  }();
  return names;
}

std::vector<std::string> add_output_flags(CLI::App* cmd, OutputFlags& o) {
  const std::vector<CLI::Option*> options = {
      cmd->add_option("--out", o.out, "Output name: writes NAME.exr, NAME.png, NAME.ply, NAME.glb (default: scene name)"),
      cmd->add_option("--width", o.width, "Image width (default: the camera's aspect times the height)")->check(CLI::Range(1, kMaxImageSide)),
      cmd->add_option("--height", o.height, "Image height (default: 512, or the width over the camera's aspect)")->check(CLI::Range(1, kMaxImageSide)),
      cmd->add_option("--exposure", o.exposure, "PNG exposure in stops")->check(finite_in(-64.0, 64.0)),
      cmd->add_flag("--flat", o.flat, "Flat-shaded image (one value per patch) instead of Gouraud"),
      cmd->add_option("--final-gather", o.final_gather_spp,
                      "Image the view by a final gather with this many samples per pixel (direct light traced, indirect "
                      "from the solution; EXR passes direct, indirect) instead of drawing the patches (0: draw them)")
          ->check(CLI::Range(0, 65536)),
      cmd->add_flag("--skip-degenerate", o.skip_degenerate, "Drop zero-area triangles instead of failing"),
      cmd->add_flag("--two-sided", o.two_sided,
                    "Every surface two-sided, as in Cycles: both sides receive, reflect and emit (per material: MTL "
                    "sirad_two_sided 1)"),
      cmd->add_flag("--allow-outside-uris", o.outside_uris,
                    "A glTF's external buffers and images may be read from outside its folder (../textures); by default "
                    "only its folder and below"),
      cmd->add_option("--camera", o.camera,
                      "The view of the images: \"eye X Y Z look X Y Z up X Y Z fov DEG\" (default: the scene's, else one "
                      "chosen to see the most)")};
  std::vector<std::string> names;
  options[5]->excludes(options[4]);  // --final-gather traces the view: --flat would have no effect
  for (const CLI::Option* opt : options) names.push_back("--" + opt->get_lnames().front());
  return names;
}

void add_lightmap_flags(CLI::App* cmd, LightmapFlags& l, bool with_switch) {
  if (with_switch)
    cmd->add_flag("--lightmap", l.on,
                  "Also bake a lightmap: NAME-lightmap.exr (half-float radiance; layers direct, indirect, error, coverage), "
                  "NAME-lightmap.png, NAME-baked.glb (TEXCOORD_1 and the lightmap; what sirad bake writes)");
  cmd->add_option("--texel-size", l.texel_size, "Lightmap texel side in the scene's units (default: from --texels)")
      ->check(finite_in(1e-9, 1e9));
  cmd->add_option("--texels", l.texels, "Lightmap texel budget: the texel size that covers the scene with about this many")
      ->check(CLI::Range(uint64_t{1024}, uint64_t{1} << 26))
      ->capture_default_str();
  cmd->add_option("--texel-samples", l.samples, "Final-gather samples per lightmap texel (each: --texel-lights emitter samples, a gather ray)")
      ->check(CLI::Range(2, 4096))
      ->capture_default_str();
  cmd->add_option("--texel-lights", l.lights,
                  "Emitter samples per texel sample (more: less noise in the direct light for fewer gather rays; "
                  "bench/RESULTS.md has the trade)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  cmd->add_flag("--own-atlas", l.own_atlas,
                "Lay the lightmap out in sirad's own charts even where the scene has its own lightmap UV set (glTF TEXCOORD_1, "
                "used by default)");
}

std::vector<std::string> output_args(const OutputFlags& o) {
  std::vector<std::string> a;
  if (o.width > 0) a.insert(a.end(), {"--width", std::to_string(o.width)});
  if (o.height > 0) a.insert(a.end(), {"--height", std::to_string(o.height)});
  if (o.exposure != 0.0f) a.insert(a.end(), {"--exposure", fmt::format("{}", o.exposure)});  // shortest exact form
  if (o.flat) a.push_back("--flat");
  if (o.final_gather_spp > 0) a.insert(a.end(), {"--final-gather", std::to_string(o.final_gather_spp)});
  if (o.skip_degenerate) a.push_back("--skip-degenerate");
  if (o.two_sided) a.push_back("--two-sided");
  if (o.outside_uris) a.push_back("--allow-outside-uris");
  if (!o.camera.empty()) a.insert(a.end(), {"--camera", o.camera});
  return a;
}

void parse_output_args(const std::vector<std::string>& args, OutputFlags& flags, const std::string& origin) {
  CLI::App app{"outputs"};
  OutputFlags parsed;
  add_output_flags(&app, parsed);
  std::vector<const char*> argv{"outputs"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::Error& e) {
    fail("{}: its output flags: {}", origin, e.what());
  }
  if (!parsed.out.empty()) fail("{}: its output flags name --out", origin);
  parsed.out = flags.out;
  flags = parsed;
}

std::set<std::string> given_flags(const CLI::App* cmd) {
  std::set<std::string> out;
  for (const CLI::Option* o : cmd->get_options())
    if (o->count() > 0)
      for (const std::string& name : o->get_lnames()) out.insert("--" + name);
  return out;
}

MeshOptions mesh_options_from(const RunFlags& flags, const std::set<std::string>& given) {
  return settings_from(flags, given).mesh_options;
}

cluster::RunSettings settings_from(const RunFlags& f, const std::set<std::string>& given) {
  if (given.count("--patches") && given.count("--max-edge")) fail("--patches and --max-edge exclude each other");
  cluster::RunSettings s;
  for (const cluster::SettingRow& row : cluster::setting_rows()) {
    const std::string flag = "--" + std::string(row.flag);
    auto typed = f.text.find(std::string(row.flag));
    const bool is_given = given.count(flag) && typed != f.text.end();
    if (!is_given && row.default_text.empty()) continue;  // the setting's own default (auto, none)
    try {
      row.parse(s, is_given ? typed->second : std::string(row.default_text));
    } catch (const Error& e) {
      fail("{}: {}", flag, e.what());
    }
  }
  if (s.target_error > 0 && !given.count("--bundles")) s.bundles = static_cast<uint64_t>(kTargetErrorCap);
  cluster::check(s);
  return s;
}

std::optional<Camera> camera_flag(const std::string& camera) {
  if (camera.empty()) return std::nullopt;
  try {
    return parse_camera(camera);
  } catch (const Error& e) {
    fail("--camera '{}': {}", camera, e.what());
  }
}

void settle_image_size(int& width, int& height, const std::optional<double>& aspect) {
  const double a = aspect.value_or(1.0);
  auto side = [](double x) { return static_cast<int>(std::clamp(std::lround(x), 1L, static_cast<long>(kMaxImageSide))); };
  if (width == 0 && height == 0) height = kDefaultImageHeight;
  if (width == 0) width = side(height * a);
  if (height == 0) height = side(width / a);
  if (int64_t{width} * height > kMaxImagePixels)
    fail("image {}x{} (--width, --height): more than {} pixels", width, height, kMaxImagePixels);
}

void settle_image_size(OutputFlags& flags, const Scene& scene) {
  settle_image_size(flags.width, flags.height, flags.camera.empty() ? scene.camera_aspect : std::nullopt);
}

ResultOptions result_options(const OutputFlags& flags) {
  if (flags.width < 1 || flags.height < 1) fail("image size {}x{} not settled (settle_image_size)", flags.width, flags.height);
  ResultOptions ro;
  ro.width = flags.width;
  ro.height = flags.height;
  ro.exposure = flags.exposure;
  ro.shading = flags.flat ? Shading::flat : Shading::gouraud;
  ro.final_gather_spp = flags.final_gather_spp;
  return ro;
}

}  // namespace sirad::cli
