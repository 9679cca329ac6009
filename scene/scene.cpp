// sirad: scene import (line-exact OBJ and MTL parsing), validation, built-ins.
#include "scene/scene.h"

#include "util/atomic_file.h"

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>
#include <map>
#include <new>
#include <numbers>
#include <sstream>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>

#include "scene/gltf.h"
#include "scene/import.h"
#include "scene/ply.h"
#include "util/error.h"
#include "util/polygon.h"
#include "util/resources.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;

// Limits against hostile input. Real radiosity scenes are orders of magnitude smaller.
using import::kDefaultReflectance;
using import::kMaxTriangles;
using import::kMaxVertices;
using import::printable;
using import::read_file;
constexpr std::size_t kMaxObjects = std::size_t{1} << 20;
constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// Supplies an MTL file named by `mtllib` on OBJ line `line`: its label for messages, its text.
using MtlSource =
    std::function<std::pair<std::string, std::string>(const std::string& file, uint32_t line)>;

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

void split(std::string_view s, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_blank(s[i])) ++i;
    const std::size_t start = i;
    while (i < s.size() && !is_blank(s[i])) ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
}

bool is_identifier(std::string_view s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  });
}

// A material name as written after `newmtl` / `usemtl`: trailing comment and blanks removed.
std::string material_name(std::string_view s) {
  return std::string(trim(s.substr(0, s.find('#'))));
}

enum class Parsed { ok, not_a_number, out_of_range };

// A whole token as a float (decimal or exponent form, optional sign). "nan"/"inf" parse; the
// caller checks finiteness. Values beyond float range are out_of_range.
Parsed parse_float(std::string_view s, float& out) {
  if (s.size() > 1 && s[0] == '+' && s[1] != '-') s.remove_prefix(1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ptr != s.data() + s.size() || ec == std::errc::invalid_argument)
    return Parsed::not_a_number;
  if (ec == std::errc::result_out_of_range || (std::isfinite(v) && std::fabs(v) > FLT_MAX))
    return Parsed::out_of_range;
  out = static_cast<float>(v);
  return Parsed::ok;
}

// A zero-area or collinear triangle: |cross| <= 1e-12 * longest_edge^2, in double.
bool is_degenerate(const std::array<glm::vec3, 3>& p) {
  const glm::dvec3 a(p[0]), b(p[1]), c(p[2]);
  const double longest2 =
      std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
  return !(glm::length(glm::cross(b - a, c - a)) > 1e-12 * longest2);
}

// One material of an MTL file: its name, Kd, Ke and sirad_two_sided, and the texture maps it
// names (not read; said in a warning).
struct MtlMaterial {
  Material material;
  std::string textures;
};

// An MTL file read line by line, as strictly as the OBJ: `Kd` and `Ke` take one number (then
// g = b = r, as the MTL convention has it) or three, each a finite float, else an error naming
// the file and line; `spectral` and `xyz` colours are refused; `sirad_two_sided` is 0 or 1.
// Every other statement (Ka, Ks, Ns, d, Tr, illum, the PBR extension, ...) is ignored, as are
// colours before the first `newmtl`. Materials come in file order.
std::vector<MtlMaterial> parse_mtl(const std::string& text, const std::string& label) {
  std::vector<MtlMaterial> out;
  std::vector<std::string_view> words;
  uint32_t line_no = 0;
  for (std::size_t at = 0; at <= text.size();) {
    std::size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + at, end - at);
    at = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string_view content = trim(line.substr(0, line.find('#')));
    if (content.empty()) continue;
    split(content, words);
    const std::string_view key = words[0];
    auto bad = [&](const std::string& what) { fail("{}:{}: {}", label, line_no, what); };
    if (key == "newmtl") {
      const std::string name = material_name(trim(line).substr(6));
      if (name.empty()) bad("newmtl without a name");
      out.push_back({{name, glm::vec3(0.0f), glm::vec3(0.0f)}, {}});
    } else if (key == "Kd" || key == "Ke") {
      if (words.size() > 1 && (words[1] == "spectral" || words[1] == "xyz"))
        bad(fmt::format("{} {}: only RGB colours are read", key, printable(words[1])));
      if (words.size() != 2 && words.size() != 4)
        bad(fmt::format("{} takes 1 or 3 numbers (got {})", key, words.size() - 1));
      glm::vec3 v(0.0f);
      for (std::size_t k = 1; k < words.size(); ++k) {
        float f = 0;
        if (parse_float(words[k], f) != Parsed::ok || !std::isfinite(f))
          bad(fmt::format("{}: '{}' is not a finite number", key, printable(words[k])));
        v[static_cast<int>(k - 1)] = f;
      }
      if (words.size() == 2) v = glm::vec3(v.x);
      if (out.empty()) continue;  // before any newmtl: no material has it
      (key == "Kd" ? out.back().material.reflectance : out.back().material.emission) = v;
    } else if (key == "sirad_two_sided") {
      const std::string v = words.size() == 2 ? std::string(words[1]) : std::string(trim(content.substr(key.size())));
      if (v != "0" && v != "1") {
        if (out.empty()) bad(fmt::format("sirad_two_sided must be 0 or 1 (got '{}')", printable(v)));
        fail("{}: material '{}': sirad_two_sided must be 0 or 1 (got '{}')", label, printable(out.back().material.name), printable(v));
      }
      if (!out.empty()) out.back().material.two_sided = v == "1";
    } else if ((key == "map_Kd" || key == "map_Ke") && words.size() > 1 && !out.empty()) {
      std::string& t = out.back().textures;
      t += (t.empty() ? "" : ", ") + printable(words.back());
    }
  }
  return out;
}

void validate_material(const Material& m, const std::string& file) {
  for (int k = 0; k < 3; ++k)
    if (!(m.reflectance[k] >= 0.0f && m.reflectance[k] <= 1.0f))
      fail("{}: material '{}': Kd {} outside [0, 1]", file, printable(m.name), m.reflectance[k]);
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(m.emission[k]))
      fail("{}: material '{}': Ke {} is not finite", file, printable(m.name), m.emission[k]);
    if (m.emission[k] < 0.0f)
      fail("{}: material '{}': Ke {} is negative", file, printable(m.name), m.emission[k]);
  }
}

// An OBJ file parsed line by line so that every message can name its line; faces are kept as
// vertex indices until the end, when vertices and materials are resolved and each face is cut
// into triangles (util/polygon.h: a convex face as its fan, a concave one by ear clipping).
class ObjParser {
 public:
  explicit ObjParser(std::string name) : name_(std::move(name)) {}

  void parse(std::string_view text) {
    if (text.size() > kMaxInputFileBytes) fail("{}: file is larger than 2 GiB", name_);
    std::size_t pos = 0;
    while (pos < text.size()) {
      std::size_t end = text.find_first_of("\r\n", pos);
      if (end == std::string_view::npos) end = text.size();
      ++line_;
      statement(text.substr(pos, end - pos));
      const bool crlf = end + 1 < text.size() && text[end] == '\r' && text[end + 1] == '\n';
      pos = end + (crlf ? 2 : 1);
    }
  }

  Scene finish(const MtlSource& source, const ImportOptions& options);

 private:
  struct RawFace {
    uint32_t first, count;  // its corners: corners_[first, first + count)
    uint32_t line;
    uint32_t slot;  // index into slots_, or kNone without a material
    uint32_t object;  // index into objects_
  };

  template <typename... Args>
  [[noreturn]] void error(fmt::format_string<Args...> f, Args&&... args) const {
    fail("{}:{}: {}", name_, line_, fmt::format(f, std::forward<Args>(args)...));
  }

  void statement(std::string_view line) {
    // Step 1: reject binary data (control bytes other than tab).
    for (char ch : line) {
      const auto c = static_cast<unsigned char>(ch);
      if ((c < 0x20 && c != '\t') || c == 0x7f) error("binary data, not OBJ text");
    }
    // Step 2: comments (maybe the camera), then the statement without a trailing comment.
    std::string_view s = trim(line);
    if (s.empty()) return;
    if (s[0] == '#') {
      comment(s.substr(1));
      return;
    }
    s = trim(s.substr(0, s.find('#')));
    split(s, tokens_);
    const std::string_view key = tokens_[0];
    if (key == "v") {
      vertex();
    } else if (key == "f") {
      face();
    } else if (key == "usemtl") {
      usemtl(material_name(s.substr(key.size())));
    } else if (key == "mtllib") {
      if (tokens_.size() < 2) error("mtllib without a file name");
      for (std::size_t i = 1; i < tokens_.size(); ++i) {
        const std::string file(tokens_[i]);
        if (std::none_of(mtllibs_.begin(), mtllibs_.end(),
                         [&](const auto& m) { return m.first == file; }))
          mtllibs_.emplace_back(file, line_);
      }
    } else if (key == "o" || key == "g") {
      // An object or group: its name (the rest of the line) names the faces that follow.
      std::string name(trim(s.substr(1)));
      if (name.empty()) name = "(unnamed)";
      auto [it, added] = object_of_.try_emplace(name, static_cast<uint32_t>(objects_.size()));
      if (added) {
        if (objects_.size() >= kMaxObjects) error("more than {} objects", kMaxObjects);
        objects_.push_back(name);
      }
      object_ = it->second;
    } else if (!is_identifier(key)) {
      // Other OBJ statements (vt, vn, s, l, ...) carry nothing a radiosity scene uses.
      error("not an OBJ statement: '{}'", printable(key));
    }
  }

  void vertex() {
    if (tokens_.size() < 4) error("vertex needs 3 coordinates");
    glm::vec3 p;
    for (int k = 0; k < 3; ++k) {
      const std::string_view t = tokens_[k + 1];
      switch (parse_float(t, p[k])) {
        case Parsed::not_a_number:
          error("bad vertex coordinate '{}'", printable(t));
        case Parsed::out_of_range:
          error("vertex coordinate '{}' out of range", printable(t));
        case Parsed::ok:
          break;
      }
      if (!std::isfinite(p[k])) error("vertex has a non-finite coordinate");
    }
    if (vertices_.size() >= kMaxVertices) error("more than {} vertices", kMaxVertices);
    vertices_.push_back(p);
  }

  void face() {
    const std::size_t count = tokens_.size() - 1;
    if (count < 3) error("face has {} vertices, needs at least 3", count);
    face_.clear();
    for (std::size_t i = 1; i <= count; ++i) {
      std::string_view ref = tokens_[i].substr(0, tokens_[i].find('/'));
      if (ref.size() > 1 && ref[0] == '+' && ref[1] != '-') ref.remove_prefix(1);
      int64_t k = 0;
      const auto [ptr, ec] = std::from_chars(ref.data(), ref.data() + ref.size(), k);
      if (ref.empty() || ptr != ref.data() + ref.size() || ec == std::errc::invalid_argument)
        error("bad face index '{}'", printable(tokens_[i]));
      if (ec == std::errc::result_out_of_range)
        error("face index {} out of range ({} vertices)", printable(ref), vertices_.size());
      if (k == 0) error("face index 0 is invalid (OBJ indices start at 1)");
      // Negative indices count back from the latest vertex; positive ones are checked at the
      // end (they may refer to vertices defined further down).
      const int64_t index = k > 0 ? k - 1 : static_cast<int64_t>(vertices_.size()) + k;
      if (index < 0 || index >= static_cast<int64_t>(kMaxVertices))
        error("face index {} out of range ({} vertices)", k, vertices_.size());
      face_.push_back(static_cast<uint32_t>(index));
    }
    if (triangle_bound_ + (count - 2) > kMaxTriangles)
      error("more than {} triangles", kMaxTriangles);
    triangle_bound_ += count - 2;
    faces_.push_back({static_cast<uint32_t>(corners_.size()), static_cast<uint32_t>(count), line_, slot_, object_});
    corners_.insert(corners_.end(), face_.begin(), face_.end());
  }

  void usemtl(const std::string& name) {
    // Blender writes `usemtl` and no name for an empty material slot: the default material.
    if (name.empty()) {
      slot_ = kNone;
      return;
    }
    const auto [it, added] = slot_of_.try_emplace(name, static_cast<uint32_t>(slots_.size()));
    if (added) slots_.push_back(name);
    slot_ = it->second;
  }

  // `# sirad camera eye X Y Z look X Y Z up X Y Z fov DEG`, keywords in any order, all required.
  void comment(std::string_view body) {
    split(body, tokens_);
    if (tokens_.size() < 2 || tokens_[0] != "sirad" || tokens_[1] != "camera") return;
    if (camera_) error("malformed '# sirad camera' line: a second camera line");
    try {
      camera_ = parse_camera(body.substr(static_cast<std::size_t>(tokens_[1].data() + tokens_[1].size() - body.data())));
    } catch (const Error& e) {
      error("malformed '# sirad camera' line: {}", e.what());
    }
  }

  std::string name_;
  uint32_t line_ = 0;
  std::vector<std::string_view> tokens_;
  std::vector<uint32_t> face_;
  std::vector<glm::vec3> vertices_;
  std::vector<RawFace> faces_;
  std::vector<uint32_t> corners_;  // the faces' vertex indices
  std::size_t triangle_bound_ = 0;  // sum over faces of corners - 2
  std::vector<std::string> slots_;  // material names in order of first `usemtl`
  std::unordered_map<std::string, uint32_t> slot_of_;
  uint32_t slot_ = kNone;
  std::vector<std::string> objects_{"(unnamed)"};
  std::unordered_map<std::string, uint32_t> object_of_{{"(unnamed)", 0}};
  uint32_t object_ = 0;
  std::vector<std::pair<std::string, uint32_t>> mtllibs_;  // file and line, first mention
  std::optional<Camera> camera_;
};

Scene ObjParser::finish(const MtlSource& source, const ImportOptions& options) {
  // Step 1: material libraries (parse_mtl); the first definition of a name wins.
  struct Defined {
    Material material;
    std::string file;
  };
  std::unordered_map<std::string, Defined> defined;
  std::map<std::string, std::string> texture_notes;  // by material name
  for (const auto& [file, line] : mtllibs_) {
    const auto [label, text] = source(file, line);
    if (text.find('\0') != std::string::npos) fail("{}: binary data, not MTL text", label);
    for (MtlMaterial& m : parse_mtl(text, label)) {
      if (!m.textures.empty())
        texture_notes.emplace(m.material.name, fmt::format("{}: material '{}': texture maps are not read ({}); its Kd and Ke "
                                                           "are used as they are", label, printable(m.material.name), m.textures));
      defined.try_emplace(m.material.name, Defined{m.material, label});
    }
  }

  // Step 2: triangles in file order: indices in range, non-degenerate, materials resolved and
  // validated on first use (Scene::materials holds only used ones, in order of first use).
  Scene scene;
  scene.name = name_;
  scene.camera = camera_;
  scene.objects = objects_;
  std::vector<uint32_t> index_of_slot(slots_.size(), kNone);
  uint32_t default_index = kNone;
  std::size_t skipped = 0, without_material = 0;
  uint32_t first_without_material = 0;  // its line
  scene.triangles.reserve(triangle_bound_);
  std::vector<glm::vec3> corners;
  for (const RawFace& raw : faces_) {
    line_ = raw.line;
    const std::span<const uint32_t> v(corners_.data() + raw.first, raw.count);
    corners.clear();
    for (uint32_t k : v) {
      if (k >= vertices_.size()) error("face index {} out of range ({} vertices)", k + 1, vertices_.size());
      corners.push_back(vertices_[k]);
    }
    std::vector<std::array<uint32_t, 3>> cut;
    try {
      cut = triangulate_polygon(corners);
    } catch (const Error& e) {
      error("{}", e.what());
    }
    for (const auto& c : cut) {
      Triangle t;
      for (int k = 0; k < 3; ++k) t.p[k] = corners[c[k]];
      if (is_degenerate(t.p)) {
        if (!options.skip_degenerate)
          error("degenerate triangle (zero area) with vertices {}, {}, {}", v[c[0]] + 1, v[c[1]] + 1, v[c[2]] + 1);
        ++skipped;
        continue;
      }
      if (raw.slot == kNone && without_material++ == 0) first_without_material = raw.line;
      uint32_t& index = raw.slot == kNone ? default_index : index_of_slot[raw.slot];
      if (index == kNone) {
        index = static_cast<uint32_t>(scene.materials.size());
        if (raw.slot == kNone) {
          scene.materials.push_back({"default", glm::vec3(kDefaultReflectance), glm::vec3(0.0f)});
        } else {
          const auto it = defined.find(slots_[raw.slot]);
          if (it == defined.end())
            error("unknown material '{}' (not defined in any material library)",
                  printable(slots_[raw.slot]));
          validate_material(it->second.material, it->second.file);
          scene.materials.push_back(it->second.material);
          if (auto note = texture_notes.find(slots_[raw.slot]); note != texture_notes.end())
            scene.warnings.push_back(note->second);
        }
      }
      t.material = index;
      t.source_line = raw.line;
      t.object = raw.object;
      scene.triangles.push_back(t);
    }
  }
  if (without_material > 0)
    scene.warnings.push_back(fmt::format("{}:{}: {} triangles have no material (no usemtl, or one without a name): they "
                                         "take the default, reflectance {} and one-sided", name_,
                                         first_without_material, without_material, kDefaultReflectance));

  // Step 3: something to solve: a triangle and an emitter.
  if (scene.triangles.empty()) {
    if (skipped > 0) fail("{}: scene has no triangles ({} skipped as degenerate)", name_, skipped);
    fail("{}: scene has no triangles", name_);
  }
  const bool emits = std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) { return m.emits(); });
  if (!emits) fail("{}: scene has no emitter (no material with Ke > 0)", name_);
  return scene;
}

// Runs an import, turning exhaustion of memory into a one-line error.
template <typename F>
Scene guarded(const std::string& name, F&& import) {
  try {
    return import();
  } catch (const std::bad_alloc&) {
    fail("{}: out of memory", name);
  } catch (const std::length_error&) {
    fail("{}: out of memory", name);
  }
}

Scene import_obj(const std::string& name, std::string_view text, const MtlSource& source,
                 const ImportOptions& options) {
  return guarded(name, [&] {
    ObjParser parser(name);
    parser.parse(text);
    return parser.finish(source, options);
  });
}

}  // namespace

namespace import {

std::string read_file(const std::filesystem::path& path, const std::string& label) {
  return read_regular_file(path.string(), label, kMaxInputFileBytes, "file is larger than 2 GiB");
}

std::string printable(std::string_view s) {
  std::string out;
  for (char ch : s.substr(0, 40)) {
    const auto c = static_cast<unsigned char>(ch);
    out += (c >= 0x20 && c < 0x7f) ? ch : '?';
  }
  if (s.size() > 40) out += "...";
  return out;
}

std::string without_controls(std::string_view s, std::size_t max) {
  std::string out(s.substr(0, max));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) == 0x7f) c = '?';
  return out;
}

double srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

}  // namespace import

void add_back_faces(Scene& scene);

namespace {

// The import options that apply after parsing: --two-sided.
Scene with_options(Scene scene, const ImportOptions& options) {
  if (options.two_sided)
    for (Material& m : scene.materials) m.two_sided = true;
  add_back_faces(scene);
  cut_along_gaps(scene);
  mark_unlit_faces(scene);
  return scene;
}

}  // namespace

Scene parse_obj(const std::string& name, const std::string& obj_text,
                const std::vector<std::pair<std::string, std::string>>& mtl_files,
                const ImportOptions& options) {
  const MtlSource source = [&](const std::string& file, uint32_t line) {
    for (const auto& [mtl_name, text] : mtl_files)
      if (mtl_name == file) return std::pair{mtl_name, text};
    fail("{}:{}: material library '{}' not provided", name, line, printable(file));
  };
  return with_options(import_obj(name, obj_text, source, options), options);
}

glm::dvec2 UvMap::at(const glm::dvec3& p) const {
  const glm::dvec3 r = p - origin;
  return uv0 + glm::dvec2(glm::dot(mu, r), glm::dot(mv, r));
}

bool make_uv_map(const std::array<glm::dvec3, 3>& p, const std::array<glm::dvec2, 3>& uv, UvMap& out) {
  // p - p0 = s e1 + t e2 in the plane; (s, t) from the Gram matrix of e1 and e2, and the UV is
  // uv0 + s d1 + t d2.
  const glm::dvec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
  const glm::dvec2 d1 = uv[1] - uv[0], d2 = uv[2] - uv[0];
  const double a = glm::dot(e1, e1), b = glm::dot(e1, e2), c = glm::dot(e2, e2), det = a * c - b * b;
  if (!(det > 1e-12 * a * c) || !(std::abs(d1.x * d2.y - d1.y * d2.x) > 0.0)) return false;
  const glm::dvec3 f1 = (c * e1 - b * e2) / det, f2 = (a * e2 - b * e1) / det;
  UvMap m;
  m.origin = p[0], m.uv0 = uv[0];
  m.mu = d1.x * f1 + d2.x * f2;
  m.mv = d1.y * f1 + d2.y * f2;
  for (const glm::dvec3& v : {m.mu, m.mv})
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) return false;
  out = m;
  return true;
}

bool is_builtin_scene(const std::string& name) {
  return name == "cornell" || name == "furnace" || name == "bright-room" || name == "three-lights";
}

Scene load_scene(const std::string& spec, const ImportOptions& options) {
  if (spec == "cornell") return with_options(builtin_cornell(), options);
  if (spec == "furnace") return with_options(builtin_furnace(), options);
  if (spec == "bright-room") return with_options(builtin_bright_room(), options);
  if (spec == "three-lights") return with_options(builtin_three_lights(), options);
  const fs::path path(spec);
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".gltf" || extension == ".glb") return with_options(guarded(spec, [&] { return import_gltf(spec, options); }), options);
  if (extension == ".ply") return with_options(guarded(spec, [&] { return import_ply(spec, options); }), options);
  if (extension != ".obj")
    fail("{}: unsupported scene format (supported: .obj, .gltf, .glb, .ply; built-ins: cornell, furnace, bright-room, three-lights)", spec);
  return guarded(spec, [&] {
    const std::string text = read_file(path, spec);
    const fs::path dir = path.parent_path();
    const MtlSource source = [&](const std::string& file, uint32_t) {
      const fs::path mtl = dir / file;
      return std::pair{mtl.string(), read_file(mtl, mtl.string())};
    };
    return with_options(import_obj(spec, text, source, options), options);
  });
}

Scene builtin_cornell() {
  const std::string obj(resource("scenes/cornell_box.obj"));
  const std::string mtl(resource("scenes/cornell_box.mtl"));
  Scene scene = parse_obj("cornell", obj, {{"cornell_box.mtl", mtl}});
  scene.name = "cornell";
  return scene;
}

// An embedded OBJ with its MTL, named like a built-in in messages.
Scene builtin_from(const char* name, const char* obj_file, const char* mtl_file) {
  const std::string obj(resource(std::string("scenes/") + obj_file));
  const std::string mtl(resource(std::string("scenes/") + mtl_file));
  Scene scene = parse_obj(name, obj, {{mtl_file, mtl}});
  scene.name = name;
  return scene;
}

Scene builtin_bright_room() { return builtin_from("bright-room", "bright_room.obj", "bright_room.mtl"); }
Scene builtin_three_lights() { return builtin_from("three-lights", "three_lights.obj", "three_lights.mtl"); }

Scene builtin_furnace() {
  Scene scene;
  scene.name = "furnace";
  scene.materials.push_back({"furnace", glm::vec3(0.5f), glm::vec3(1.0f)});
  // Each face of the unit cube as a quad q0..q3 spanning the two other axes u, v (so its normal
  // is +axis); on the far side (coordinate 1) reversed, so every normal points into the cube.
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      std::array<glm::vec3, 4> q;
      const float uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
      for (int k = 0; k < 4; ++k) {
        q[k][axis] = static_cast<float>(side);
        q[k][u] = uv[k][0];
        q[k][v] = uv[k][1];
      }
      if (side == 1) std::swap(q[1], q[3]);
      scene.triangles.push_back({{q[0], q[1], q[2]}, 0, 0});
      scene.triangles.push_back({{q[0], q[2], q[3]}, 0, 0});
    }
  }
  scene.camera = Camera{{0.5f, 0.5f, 0.05f}, {0.5f, 0.5f, 1.0f}, {0.0f, 1.0f, 0.0f}, 90.0f};
  return scene;
}

std::vector<std::string> builtin_scene_names() { return {"cornell", "furnace", "bright-room", "three-lights"}; }

Camera parse_camera(std::string_view spec) {
  std::vector<std::string_view> tokens;
  split(spec, tokens);
  std::map<std::string_view, glm::vec3> given;
  for (std::size_t i = 0; i < tokens.size();) {
    const std::string_view key = tokens[i++];
    const int arity = key == "fov" ? 1 : (key == "eye" || key == "look" || key == "up") ? 3 : 0;
    if (arity == 0) fail("unknown keyword '{}'", printable(key));
    if (given.count(key)) fail("'{}' given twice", key);
    if (i + arity > tokens.size()) fail("'{}' needs {} number{}", key, arity, arity == 1 ? "" : "s");
    glm::vec3 value(0.0f);
    for (int k = 0; k < arity; ++k, ++i)
      if (parse_float(tokens[i], value[k]) != Parsed::ok || !std::isfinite(value[k]))
        fail("'{}' has a bad number '{}'", key, printable(tokens[i]));
    given[key] = value;
  }
  for (const char* key : {"eye", "look", "up", "fov"})
    if (!given.count(key)) fail("missing '{}'", key);
  Camera camera{given["eye"], given["look"], given["up"], given["fov"].x};
  if (!(camera.vfov_deg > 0.0f && camera.vfov_deg < 180.0f)) fail("fov {} outside (0, 180)", camera.vfov_deg);
  const glm::dvec3 view = glm::dvec3(camera.look_at) - glm::dvec3(camera.eye);
  const glm::dvec3 up(camera.up);
  if (!(glm::length(view) > 0.0)) fail("eye and look are the same point");
  if (!(glm::length(glm::cross(view, up)) > 1e-6 * glm::length(view) * glm::length(up)))
    fail("up is zero or parallel to the view direction");
  return camera;
}

std::string camera_spec(const Camera& c) {
  return fmt::format("eye {} {} {} look {} {} {} up {} {} {} fov {}", c.eye.x, c.eye.y, c.eye.z, c.look_at.x, c.look_at.y,
                     c.look_at.z, c.up.x, c.up.y, c.up.z, c.vfov_deg);
}

Camera default_camera(const Scene& scene) {
  Camera camera;
  if (scene.triangles.empty()) {
    camera.eye = {0.0f, 0.0f, -1.0f};
    camera.look_at = {0.0f, 0.0f, 0.0f};
    return camera;
  }
  // Look at the bounding box centre along +Z from far enough that its bounding sphere fits
  // the vertical field of view.
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Triangle& t : scene.triangles)
    for (const glm::vec3& p : t.p) {
      lo = glm::min(lo, glm::dvec3(p));
      hi = glm::max(hi, glm::dvec3(p));
    }
  const glm::dvec3 centre = 0.5 * (lo + hi);
  double radius = 0.5 * glm::length(hi - lo);
  if (!(radius > 0.0)) radius = 1.0;
  const double distance = radius / std::sin(0.5 * camera.vfov_deg * std::numbers::pi / 180.0);
  camera.look_at = glm::vec3(centre);
  camera.eye = glm::vec3(centre - glm::dvec3(0.0, 0.0, distance));
  camera.up = {0.0f, 1.0f, 0.0f};
  return camera;
}

}  // namespace sirad
