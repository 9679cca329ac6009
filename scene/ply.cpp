// sirad: PLY scenes (scene/ply.h). Debian packages no PLY library (assimp reads PLY but
// drops the per-face properties that carry emission), so this is a small reader of the format
// written by hand, strict about what it reads: the header's elements and properties, then
// ascii, binary_little_endian or binary_big_endian bodies, every count bounded by the file's
// size before anything is allocated.
//
// What a face's material is: its float properties reflectance_r/g/b and emission_r/g/b when
// present (sirad's own PLY, so a solution's PLY is a scene again), else the face's or its first
// vertex's red/green/blue (bytes / 255, sRGB-decoded; floats as they are) as reflectance, else
// 0.8. Faces with equal properties share one material. Polygons are cut into triangles by
// triangulate_polygon (util/polygon.h: convex ones as their fan, concave ones by ear clipping).
#include "scene/ply.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "scene/import.h"
#include "util/error.h"
#include "util/polygon.h"

namespace sirad {

namespace {

using import::kMaxTriangles;
using import::kMaxVertices;
using import::srgb_to_linear;

enum class Type { i8, u8, i16, u16, i32, u32, f32, f64 };

struct Property {
  std::string name;
  Type type = Type::f32;
  bool list = false;
  Type count_type = Type::u8;
};

struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> properties;
  int find(const std::string& n) const {
    for (std::size_t i = 0; i < properties.size(); ++i)
      if (properties[i].name == n) return static_cast<int>(i);
    return -1;
  }
};

std::size_t size_of(Type t) {
  switch (t) {
    case Type::i8: case Type::u8: return 1;
    case Type::i16: case Type::u16: return 2;
    case Type::i32: case Type::u32: case Type::f32: return 4;
    case Type::f64: return 8;
  }
  return 0;
}

bool parse_type(const std::string& s, Type& t) {
  static const std::map<std::string, Type> names = {
      {"char", Type::i8},    {"int8", Type::i8},   {"uchar", Type::u8},   {"uint8", Type::u8},
      {"short", Type::i16},  {"int16", Type::i16}, {"ushort", Type::u16}, {"uint16", Type::u16},
      {"int", Type::i32},    {"int32", Type::i32}, {"uint", Type::u32},   {"uint32", Type::u32},
      {"float", Type::f32},  {"float32", Type::f32}, {"double", Type::f64}, {"float64", Type::f64}};
  auto it = names.find(s);
  if (it == names.end()) return false;
  t = it->second;
  return true;
}

// Text from the file as it may appear in a message.
std::string clean(const std::string& text) { return import::without_controls(text, 40); }

// Reads values from the body: ascii tokens or binary in either byte order.
class Body {
 public:
  Body(const std::string& path, const std::string& data, std::size_t at, int format)
      : path_(path), data_(data), at_(at), format_(format) {}
  double value(Type t, const char* what) {
    if (format_ == 0) return ascii(what);
    const std::size_t n = size_of(t);
    if (data_.size() - at_ < n) fail("{}: the file ends inside {}", path_, what);
    unsigned char b[8];
    std::memcpy(b, data_.data() + at_, n);
    at_ += n;
    if (format_ == 2) std::reverse(b, b + n);
    switch (t) {
      case Type::i8: return static_cast<int8_t>(b[0]);
      case Type::u8: return b[0];
      case Type::i16: { int16_t v; std::memcpy(&v, b, 2); return v; }
      case Type::u16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
      case Type::i32: { int32_t v; std::memcpy(&v, b, 4); return v; }
      case Type::u32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
      case Type::f32: { float v; std::memcpy(&v, b, 4); return v; }
      case Type::f64: { double v; std::memcpy(&v, b, 8); return v; }
    }
    return 0.0;
  }

 private:
  double ascii(const char* what) {
    while (at_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[at_]))) ++at_;
    if (at_ >= data_.size()) fail("{}: the file ends inside {}", path_, what);
    std::size_t end = at_;
    while (end < data_.size() && !std::isspace(static_cast<unsigned char>(data_[end]))) ++end;
    const std::string token = data_.substr(at_, std::min<std::size_t>(end - at_, 64));
    at_ = end;
    char* stop = nullptr;
    double v = std::strtod(token.c_str(), &stop);
    if (token.empty() || stop != token.c_str() + token.size()) fail("{}: {}: '{}' is not a number", path_, what, clean(token));
    return v;
  }
  const std::string& path_;
  const std::string& data_;
  std::size_t at_;
  int format_;  // 0 ascii, 1 little endian, 2 big endian
};

// The header: its elements and their properties, the format, sirad's comments (camera,
// background), and where the body starts.
struct Header {
  std::vector<Element> elements;
  int format = -1;  // 0 ascii, 1 little endian, 2 big endian
  std::optional<Camera> camera;
  double error_estimate = -1.0;  // `sirad error estimate E`: the run's (a solution's PLY)
  glm::vec3 background{0.0f};
  std::size_t body = 0;
};

Header read_header(const std::string& path, const std::string& data) {
  const std::size_t file_size = data.size();
  const std::size_t end = data.find("end_header");
  if (data.rfind("ply", 0) != 0 || end == std::string::npos || end > 1 << 20) fail("{}: not a PLY file (no ply ... end_header)", path);
  Header out;
  out.body = data.find('\n', end);
  if (out.body == std::string::npos) fail("{}: nothing after end_header", path);
  ++out.body;
  std::istringstream header(data.substr(0, end));
  std::string line;
  int line_no = 0;
  std::vector<Element>& elements = out.elements;
  int& format = out.format;
  while (std::getline(header, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string key;
    words >> key;
    auto bad = [&](const std::string& why) { fail("{}: header line {}: {}", path, line_no, why); };
    if (key == "comment") {
      std::string word;
      words >> word;
      if (word != "sirad") continue;
      words >> word;
      std::string rest;
      std::getline(words, rest);
      try {
        if (word == "camera") out.camera = parse_camera(rest);
        if (word == "error") {
          std::istringstream e(rest);
          std::string estimate;
          double v = -1.0;
          if (!(e >> estimate >> v) || estimate != "estimate" || !(v >= 0.0 && v < 1e6)) fail("'estimate E', E >= 0, expected");
          out.error_estimate = v;
        }
        if (word == "background") {
          std::istringstream rgb(rest);
          glm::vec3 bg;
          if (!(rgb >> bg.x >> bg.y >> bg.z) || !(bg.x >= 0 && bg.y >= 0 && bg.z >= 0 && bg.x < 3e38f && bg.y < 3e38f && bg.z < 3e38f))
            fail("three finite non-negative numbers expected");
          out.background = bg;
        }
      } catch (const Error& e) {
        bad(fmt::format("sirad {}: {}", clean(word), e.what()));
      }
      continue;
    }
    if (key.empty() || key == "ply" || key == "obj_info") continue;
    if (key == "format") {
      std::string f, version;
      words >> f >> version;
      format = f == "ascii" ? 0 : f == "binary_little_endian" ? 1 : f == "binary_big_endian" ? 2 : -2;
      if (format == -2) bad(fmt::format("unknown format '{}'", clean(f)));
    } else if (key == "element") {
      Element e;
      long long count = -1;
      words >> e.name >> count;
      if (e.name.empty() || count < 0 || static_cast<uintmax_t>(count) > file_size) bad("element needs a name and a count the file can hold");
      e.count = static_cast<std::size_t>(count);
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) bad("property before any element");
      Property p;
      std::string t;
      words >> t;
      if (t == "list") {
        std::string ct, it;
        words >> ct >> it >> p.name;
        p.list = true;
        if (!parse_type(ct, p.count_type) || !parse_type(it, p.type)) bad("unknown list type");
      } else {
        words >> p.name;
        if (!parse_type(t, p.type)) bad(fmt::format("unknown type '{}'", clean(t)));
      }
      if (p.name.empty()) bad("property without a name");
      elements.back().properties.push_back(p);
    } else {
      bad(fmt::format("unknown keyword '{}'", clean(key)));
    }
  }
  if (format < 0) fail("{}: no format line", path);

  return out;
}

// A face as the body gives it: its vertices, and its properties (reflectance -1: none given).
struct Face {
  std::vector<uint32_t> v;
  glm::vec3 reflectance{-1.0f}, emission{0.0f}, radiosity{0.0f};
  bool in_gap = false;
};

// The body, element by element; only vertex and face are kept. `solution`: the faces must carry
// radiosity_r/g/b.
void read_body(const std::string& path, const std::string& data, const Header& h, bool solution,
               std::vector<glm::vec3>& positions, std::vector<Face>& faces) {
  Body reader(path, data, h.body, h.format);
  std::vector<glm::vec3> vertex_colour;
  bool vertex_has_colour = false;
  std::size_t triangles = 0;
  for (const Element& e : h.elements) {
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    const int x = e.find("x"), y = e.find("y"), z = e.find("z");
    const int r = e.find("red"), g = e.find("green"), b = e.find("blue");
    const int idx = std::max(e.find("vertex_indices"), e.find("vertex_index"));
    int refl[3] = {e.find("reflectance_r"), e.find("reflectance_g"), e.find("reflectance_b")};
    int emis[3] = {e.find("emission_r"), e.find("emission_g"), e.find("emission_b")};
    int rad[3] = {e.find("radiosity_r"), e.find("radiosity_g"), e.find("radiosity_b")};
    const int gap = e.find("sirad_in_gap");
    if (is_vertex) {
      if (x < 0 || y < 0 || z < 0) fail("{}: the vertex element has no x, y and z", path);
      if (e.count > kMaxVertices) fail("{}: more than {} vertices", path, kMaxVertices);
      vertex_has_colour = r >= 0 && g >= 0 && b >= 0;
    }
    if (is_face) {
      if (idx < 0 || !e.properties[static_cast<std::size_t>(idx)].list) fail("{}: the face element has no vertex_indices list", path);
      if (solution && (rad[0] < 0 || rad[1] < 0 || rad[2] < 0))
        fail("{}: not a solution: its faces have no radiosity_r/g/b (a PLY that sirad wrote has them)", path);
    }
    for (std::size_t i = 0; i < e.count; ++i) {
      glm::dvec3 p(0.0), colour(-1.0), rho(-1.0), em(0.0), solved(0.0);
      bool has_rho = refl[0] >= 0 && refl[1] >= 0 && refl[2] >= 0, has_em = emis[0] >= 0 && emis[1] >= 0 && emis[2] >= 0;
      Face f;
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const Property& prop = e.properties[k];
        const std::string what = fmt::format("{} {} property {}", clean(e.name), i, clean(prop.name));
        if (prop.list) {
          const double n = reader.value(prop.count_type, what.c_str());
          if (!(n >= 0 && n <= 1 << 16)) fail("{}: {}: list of {} entries", path, what, n);
          for (int m = 0; m < static_cast<int>(n); ++m) {
            const double v = reader.value(prop.type, what.c_str());
            if (is_face && static_cast<int>(k) == idx) {
              if (!(v >= 0 && v < static_cast<double>(positions.size())))
                fail("{}: face {}: vertex index {} out of range ({} vertices)", path, i, v, positions.size());
              f.v.push_back(static_cast<uint32_t>(v));
            }
          }
          continue;
        }
        const double v = reader.value(prop.type, what.c_str());
        const int ki = static_cast<int>(k);
        if (ki == x) p.x = v;
        if (ki == y) p.y = v;
        if (ki == z) p.z = v;
        const double c = prop.type == Type::u8 ? srgb_to_linear(v / 255.0) : v;
        if (ki == r) colour.x = c;
        if (ki == g) colour.y = c;
        if (ki == b) colour.z = c;
        if (ki == gap) {
          if (v != 0 && v != 1) fail("{}: {}: {} is neither 0 nor 1", path, what, v);
          f.in_gap = v == 1;
        }
        for (int c3 = 0; c3 < 3; ++c3) {
          if (ki == refl[c3]) rho[c3] = v;
          if (ki == emis[c3]) em[c3] = v;
          if (ki == rad[c3]) solved[c3] = v;
        }
      }
      if (is_vertex) {
        for (int c3 = 0; c3 < 3; ++c3)
          if (!std::isfinite(p[c3]) || std::abs(p[c3]) > 1e30) fail("{}: vertex {} has a non-finite coordinate", path, i);
        positions.push_back(glm::vec3(p));
        vertex_colour.push_back(glm::vec3(colour));
      }
      if (is_face) {
        if (f.v.size() < 3) fail("{}: face {} has {} vertices, needs at least 3", path, i, f.v.size());
        triangles += f.v.size() - 2;
        if (triangles > kMaxTriangles) fail("{}: more than {} triangles", path, kMaxTriangles);
        if (has_rho) f.reflectance = glm::vec3(rho);
        else if (r >= 0 && g >= 0 && b >= 0) f.reflectance = glm::vec3(colour);
        else if (vertex_has_colour) f.reflectance = vertex_colour[f.v[0]];
        if (has_em) f.emission = glm::vec3(em);
        f.radiosity = glm::vec3(solved);
        faces.push_back(std::move(f));
      }
    }
  }
  if (positions.empty() || faces.empty()) fail("{}: no vertex and face elements", path);

}

}  // namespace

Scene import_ply(const std::string& path, const ImportOptions& options, std::vector<glm::vec3>* radiosity, double* error_estimate) {
  const std::string data = import::read_file(path, path);
  const Header header = read_header(path, data);
  if (error_estimate) *error_estimate = header.error_estimate;
  std::vector<glm::vec3> positions;
  std::vector<Face> faces;
  read_body(path, data, header, radiosity != nullptr, positions, faces);

  Scene scene;
  scene.name = path;
  scene.objects = {std::filesystem::path(path).stem().string()};
  scene.camera = header.camera;
  scene.background = header.background;
  std::map<std::tuple<float, float, float, float, float, float>, uint32_t> material_of;
  std::size_t skipped = 0;
  std::vector<glm::vec3> corners;
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const Face& f = faces[i];
    glm::vec3 rho = f.reflectance.x < 0 ? glm::vec3(import::kDefaultReflectance) : f.reflectance;
    for (int c = 0; c < 3; ++c) {
      if (!(rho[c] >= 0.0f && rho[c] <= 1.0f)) fail("{}: face {}: reflectance {} outside [0, 1]", path, i, rho[c]);
      if (!std::isfinite(f.emission[c]) || f.emission[c] < 0.0f || f.emission[c] > 3e38f)
        fail("{}: face {}: emission {} is negative or not finite", path, i, f.emission[c]);
    }
    auto key = std::make_tuple(rho.x, rho.y, rho.z, f.emission.x, f.emission.y, f.emission.z);
    auto [it, added] = material_of.try_emplace(key, static_cast<uint32_t>(scene.materials.size()));
    if (added) scene.materials.push_back({fmt::format("ply material {}", scene.materials.size()), rho, f.emission});
    if (radiosity)
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(f.radiosity[c]) || std::abs(f.radiosity[c]) > 3e38f)  // an estimate may dip below 0
          fail("{}: face {}: radiosity {} is not finite", path, i, f.radiosity[c]);
    corners.clear();
    for (uint32_t v : f.v) corners.push_back(positions[v]);
    std::vector<std::array<uint32_t, 3>> cut;
    try {
      cut = triangulate_polygon(corners);
    } catch (const Error& e) {
      fail("{}: face {}: {}", path, i, e.what());
    }
    for (const auto& c : cut) {
      Triangle t;
      t.p = {corners[c[0]], corners[c[1]], corners[c[2]]};
      t.material = it->second;
      t.in_gap = f.in_gap;
      if (!(glm::length(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0]))) > 0.0)) {
        if (!options.skip_degenerate) fail("{}: face {}: degenerate triangle (zero area) (skipping degenerate triangles drops them)", path, i);
        ++skipped;
        continue;
      }
      scene.triangles.push_back(t);
      if (radiosity) radiosity->push_back(f.radiosity);
    }
  }
  if (scene.triangles.empty()) fail("{}: scene has no triangles ({} skipped as degenerate)", path, skipped);
  bool emits = false;
  for (const Material& m : scene.materials) emits = emits || m.emits();
  if (!emits) fail("{}: scene has no emitter (no face with emission_r/g/b above 0)", path);
  return scene;
}

}  // namespace sirad
