// sirad: the output files: float EXR with run attributes, tone-mapped sRGB PNG, binary PLY.
#include "io/write.h"

#include <algorithm>
#include <unordered_map>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <set>
#include <string_view>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfName.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <png.h>

#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad {

namespace {

static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "Image pixels are packed float RGB");

void check_image(const std::string& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0)
    fail("cannot write {}: empty image ({}x{})", path, image.width, image.height);
  const auto expected =
      static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
  if (image.pixels.size() != expected)
    fail("cannot write {}: image has {} pixels, {}x{} needs {}", path, image.pixels.size(),
         image.width, image.height, expected);
}

// An exception text as one line (some libraries put newlines into their messages).
std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  return text;
}

// ---- EXR ----

// Attribute names an OpenEXR reader gives a meaning (required, multi-part, deep, tiled and the
// optional standard attributes of ImfStandardAttributes.h): run settings must not take them.
bool is_standard_exr_attribute(std::string_view name) {
  // clang-format off
  static const std::set<std::string_view> names{
      "channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio",
      "screenWindowCenter", "screenWindowWidth", "tiles", "type", "name", "view", "version",
      "chunkCount", "maxSamplesPerPixel", "chromaticities", "whiteLuminance", "adoptedNeutral",
      "renderingTransform", "lookModTransform", "xDensity", "owner", "comments", "capDate",
      "utcOffset", "longitude", "latitude", "altitude", "focus", "expTime", "aperture",
      "isoSpeed", "envmap", "keyCode", "timeCode", "wrapmodes", "framesPerSecond", "multiView",
      "worldToCamera", "worldToNDC", "deepImageState", "originalDataWindow",
      "dwaCompressionLevel", "idManifest"};
  // clang-format on
  return names.contains(name);
}

void add_exr_attributes(const std::string& path, const Attributes& attributes,
                        Imf::Header& header) {
  std::set<std::string_view> seen;
  for (const auto& [name, value] : attributes) {
    if (name.empty()) fail("cannot write {}: empty EXR attribute name", path);
    if (name.size() > static_cast<std::size_t>(Imf::Name::MAX_LENGTH) ||
        name.find('\0') != std::string::npos)
      fail("cannot write {}: invalid EXR attribute name '{}'", path, name);
    if (is_standard_exr_attribute(name))
      fail("cannot write {}: EXR attribute '{}' clashes with a standard attribute", path, name);
    if (!seen.insert(name).second)
      fail("cannot write {}: EXR attribute '{}' given twice", path, name);

    if (const auto* i = std::get_if<int64_t>(&value)) {
      if (*i >= std::numeric_limits<int32_t>::min() && *i <= std::numeric_limits<int32_t>::max())
        header.insert(name, Imf::IntAttribute(static_cast<int>(*i)));
      else
        header.insert(name, Imf::DoubleAttribute(static_cast<double>(*i)));
    } else if (const auto* d = std::get_if<double>(&value)) {
      header.insert(name, Imf::DoubleAttribute(*d));
    } else {
      header.insert(name, Imf::StringAttribute(std::get<std::string>(value)));
    }
  }
}

// OpenEXR output into the atomic temporary. OutputFile writes its line offset table in its
// destructor and swallows errors there, so the first error is also kept for the caller to check.
class ExrStream : public Imf::OStream {
 public:
  explicit ExrStream(AtomicFile& file) : Imf::OStream(file.path().c_str()), file_(file) {}
  void write(const char c[], int n) override {
    const auto size = static_cast<std::size_t>(n);
    if (std::fwrite(c, 1, size, file_.stream()) != size) record_and_fail(errno);
    position_ += size;
  }
  uint64_t tellp() override { return position_; }
  void seekp(uint64_t position) override {
    if (::fseeko(file_.stream(), static_cast<off_t>(position), SEEK_SET) != 0)
      record_and_fail(errno);
    position_ = position;
  }
  int error() const { return error_; }

 private:
  [[noreturn]] void record_and_fail(int error) {
    if (error_ == 0) error_ = error != 0 ? error : EIO;
    file_.fail_errno(error_);
  }

  AtomicFile& file_;
  uint64_t position_ = 0;
  int error_ = 0;
};

// ---- PNG ----

// The sRGB transfer function of a linear value already in [0, 1].
double srgb_encode(double linear) {
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

// Tone map of one channel: scaled, clamped (NaN to 0, +Inf to 1), sRGB, rounded to 8 bits.
uint8_t tone_map(float value, double scale) {
  double v = static_cast<double>(value) * scale;
  if (std::isnan(v)) v = 0.0;
  v = std::clamp(v, 0.0, 1.0);
  return static_cast<uint8_t>(std::lround(srgb_encode(v) * 255.0));
}

// State shared with the libpng callbacks. libpng reports errors by longjmp, so everything it
// touches is trivially destructible and the C++ error is raised after it has returned.
struct PngContext {
  std::FILE* file;
  int write_errno;
  char message[256];
};

void png_on_error(png_structp png, png_const_charp message) {
  auto* context = static_cast<PngContext*>(png_get_error_ptr(png));
  std::snprintf(context->message, sizeof context->message, "%s", message);
  png_longjmp(png, 1);
}

void png_on_warning(png_structp, png_const_charp) {}

void png_on_write(png_structp png, png_bytep data, size_t size) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  if (std::fwrite(data, 1, size, context->file) != size) {
    context->write_errno = errno;
    png_error(png, "write failed");
  }
}

void png_on_flush(png_structp) {}

// Encodes 8-bit RGB rows into context->file. Returns false on a libpng error (the context says
// which). Only trivially destructible locals: libpng may leave this function by longjmp.
bool encode_png(PngContext* context, png_bytepp rows, png_uint_32 width, png_uint_32 height) {
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, context, png_on_error, png_on_warning);
  if (png == nullptr) {
    std::snprintf(context->message, sizeof context->message, "cannot initialise libpng");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(context->message, sizeof context->message, "cannot initialise libpng");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, context, png_on_write, png_on_flush);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  png_write_image(png, rows);
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return true;
}

// ---- PLY ----

// Appends values in little-endian byte order, whatever the host's.
template <typename T>
void put_le(std::vector<unsigned char>& out, T value) {
  static_assert(sizeof(T) == 4);
  const auto bits = std::bit_cast<uint32_t>(value);
  for (int shift = 0; shift < 32; shift += 8)
    out.push_back(static_cast<unsigned char>(bits >> shift));
}

void put_le(std::vector<unsigned char>& out, const glm::vec3& v) {
  put_le(out, v.x);
  put_le(out, v.y);
  put_le(out, v.z);
}

}  // namespace

void write_exr(const std::string& path, const Image& image, const Attributes& attributes) {
  write_exr_layers(path, {{"", &image}}, attributes);
}

void write_exr_layers(const std::string& path, const std::vector<std::pair<std::string, const Image*>>& layers,
                      const Attributes& attributes, ExrPixel pixel) {
  // Step 1: validate and build the header: float (or half) R, G, B per layer ("" unprefixed,
  // else LAYER.R ...), lossless ZIP, top row first.
  if (layers.empty()) fail("cannot write {}: no image", path);
  const Image& first = *layers.front().second;
  for (const auto& [name, image] : layers) {
    check_image(path, *image);
    if (image->width != first.width || image->height != first.height)
      fail("cannot write {}: layer '{}' is {}x{}, not {}x{}", path, name, image->width, image->height, first.width, first.height);
  }
  Imf::Header header(first.width, first.height);
  header.compression() = Imf::ZIP_COMPRESSION;
  header.lineOrder() = Imf::INCREASING_Y;
  std::vector<std::string> names;
  for (const auto& [name, image] : layers)
    for (const char* channel : {"R", "G", "B"}) {
      names.push_back(name.empty() ? channel : name + "." + channel);
      header.channels().insert(names.back(), Imf::Channel(pixel == ExrPixel::half ? Imf::HALF : Imf::FLOAT));
    }
  if (pixel == ExrPixel::half)
    for (const auto& [name, image] : layers)
      for (const glm::vec3& v : image->pixels)
        if (std::max({v.x, v.y, v.z}) > kHalfMax)
          fail("cannot write {}: layer '{}' has a value {} above half float's largest, {}", path, name, std::max({v.x, v.y, v.z}), kHalfMax);
  add_exr_attributes(path, attributes, header);

  // Step 2: the pixels, straight from the packed RGB floats, or rounded to half beside them.
  Imf::FrameBuffer frame;
  std::size_t n = 0;
  std::vector<std::vector<Imath::half>> halves;
  for (const auto& [name, image] : layers) {
    if (pixel == ExrPixel::half) {
      std::vector<Imath::half>& h = halves.emplace_back(image->pixels.size() * 3);
      for (std::size_t i = 0; i < image->pixels.size(); ++i)
        for (int c = 0; c < 3; ++c) h[3 * i + static_cast<std::size_t>(c)] = Imath::half(image->pixels[i][c]);
      const std::size_t x_stride = 3 * sizeof(Imath::half), y_stride = x_stride * static_cast<std::size_t>(image->width);
      for (int c = 0; c < 3; ++c)
        frame.insert(names[n++], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(h.data() + c), x_stride, y_stride));
      continue;
    }
    auto* base = const_cast<char*>(reinterpret_cast<const char*>(image->pixels.data()));
    const std::size_t x_stride = sizeof(glm::vec3);
    const std::size_t y_stride = x_stride * static_cast<std::size_t>(image->width);
    for (int c = 0; c < 3; ++c) frame.insert(names[n++], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), x_stride, y_stride));
  }

  // Step 3: write the temporary (OutputFile completes it in its destructor), then rename.
  AtomicFile file(path);
  ExrStream stream(file);
  try {
    Imf::OutputFile out(stream, header);
    out.setFrameBuffer(frame);
    out.writePixels(first.height);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    file.fail(one_line(e.what()));
  }
  if (stream.error() != 0) file.fail_errno(stream.error());
  file.commit();
}

namespace {

// The tone map's 8-bit rows of `image` (write_png), validated for `what`.
std::vector<png_byte> tone_mapped(const std::string& what, const Image& image, float exposure) {
  check_image(what, image);
  if (!std::isfinite(exposure)) fail("cannot write {}: exposure {} is not finite", what, exposure);
  const double scale = std::exp2(static_cast<double>(exposure));
  std::vector<png_byte> bytes(image.pixels.size() * 3);
  for (std::size_t i = 0; i < image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) bytes[3 * i + c] = tone_map(image.pixels[i][c], scale);
  return bytes;
}

std::vector<png_bytep> rows_of(std::vector<png_byte>& bytes, const Image& image) {
  std::vector<png_bytep> rows(static_cast<std::size_t>(image.height));
  for (std::size_t y = 0; y < rows.size(); ++y) rows[y] = bytes.data() + 3 * static_cast<std::size_t>(image.width) * y;
  return rows;
}

}  // namespace

void write_png(const std::string& path, const Image& image, float exposure) {
  // Step 1: tone map into 8-bit rows.
  std::vector<png_byte> bytes = tone_mapped(path, image, exposure);
  std::vector<png_bytep> rows = rows_of(bytes, image);

  // Step 2: encode into the temporary; libpng errors become sirad::Error here, outside libpng.
  AtomicFile file(path);
  PngContext context{file.stream(), 0, {}};
  if (!encode_png(&context, rows.data(), static_cast<png_uint_32>(image.width),
                  static_cast<png_uint_32>(image.height))) {
    if (context.write_errno != 0) file.fail_errno(context.write_errno);
    file.fail(fmt::format("libpng: {}", context.message));
  }
  file.commit();
}

std::vector<unsigned char> png_bytes(const std::string& what, const Image& image, float exposure) {
  std::vector<png_byte> bytes = tone_mapped(what, image, exposure);
  std::vector<png_bytep> rows = rows_of(bytes, image);
  char* data = nullptr;
  std::size_t size = 0;
  std::FILE* memory = open_memstream(&data, &size);
  if (memory == nullptr) fail("cannot encode {}: out of memory", what);
  PngContext context{memory, 0, {}};
  const bool done = encode_png(&context, rows.data(), static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height));
  std::fclose(memory);  // sets data and size
  std::vector<unsigned char> out(data, data + (done ? size : 0));
  std::free(data);
  if (!done) fail("cannot encode {}: libpng: {}", what, context.message);
  return out;
}

std::vector<uint32_t> split_corners(const PatchMesh& mesh, const std::vector<std::array<glm::vec3, 3>>& corners,
                                    const std::vector<uint32_t>& patches, std::vector<uint32_t>& vertex,
                                    std::vector<glm::vec3>& value) {
  struct Corner {
    uint32_t vertex;
    glm::vec3 value;
    bool operator==(const Corner& o) const { return vertex == o.vertex && std::memcmp(&value, &o.value, sizeof value) == 0; }
  };
  struct CornerHash {
    std::size_t operator()(const Corner& c) const {
      uint32_t bits[3];
      std::memcpy(bits, &c.value, sizeof bits);
      return (static_cast<std::size_t>(c.vertex) * 0x9e3779b97f4a7c15ULL) ^ (bits[0] * 0x85ebca6bULL) ^
             (bits[1] * 0xc2b2ae35ULL) ^ bits[2];
    }
  };
  std::unordered_map<Corner, uint32_t, CornerHash> index_of;
  std::vector<uint32_t> out;
  out.reserve(3 * patches.size());
  vertex.clear();
  value.clear();
  for (uint32_t j : patches)
    for (int k = 0; k < 3; ++k) {
      Corner c{mesh.patches[j][static_cast<std::size_t>(k)], corners[j][static_cast<std::size_t>(k)]};
      auto [it, added] = index_of.try_emplace(c, static_cast<uint32_t>(vertex.size()));
      if (added) {
        vertex.push_back(c.vertex);
        value.push_back(c.value);
      }
      out.push_back(it->second);
    }
  return out;
}

void write_ply(const std::string& path, const PatchMesh& mesh,
               const std::vector<glm::vec3>& radiosity, float exposure, double error_estimate) {
  // Step 1: validate what the body refers to.
  if (radiosity.size() != mesh.size())
    fail("cannot write {}: {} radiosity values for {} patches", path, radiosity.size(),
         mesh.size());
  if (mesh.material.size() != mesh.size())
    fail("cannot write {}: {} material ids for {} patches", path, mesh.material.size(),
         mesh.size());
  if (mesh.vertices.size() > static_cast<std::size_t>(std::numeric_limits<int32_t>::max()))
    fail("cannot write {}: {} vertices do not fit PLY int indices", path, mesh.vertices.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    for (uint32_t v : mesh.patches[j])
      if (v >= mesh.vertices.size())
        fail("cannot write {}: patch {} refers to vertex {} of {}", path, j, v,
             mesh.vertices.size());
    if (mesh.material[j] >= mesh.materials.size())
      fail("cannot write {}: patch {} has material {} of {}", path, j, mesh.material[j],
           mesh.materials.size());
  }
  if (std::any_of(mesh.hash.begin(), mesh.hash.end(),
                  [](char c) { return static_cast<unsigned char>(c) <= ' '; }))
    fail("cannot write {}: scene hash '{}' contains blanks or control characters", path, mesh.hash);

  if (!std::isfinite(exposure)) fail("cannot write {}: exposure is not finite", path);

  // Step 2: the vertices: one per welded position and corner value, in order of first use.
  std::vector<uint32_t> all(mesh.size()), vertex;
  for (std::size_t j = 0; j < mesh.size(); ++j) all[j] = static_cast<uint32_t>(j);
  std::vector<glm::vec3> value;
  const std::vector<uint32_t> faces = split_corners(mesh, corner_radiosity(mesh, radiosity), all, vertex, value);
  if (vertex.size() > static_cast<std::size_t>(std::numeric_limits<int32_t>::max()))
    fail("cannot write {}: {} vertices do not fit PLY int indices", path, vertex.size());
  const double scale = std::exp2(static_cast<double>(exposure));

  // Step 3: the header; the comments give what an image of the solution needs besides the
  // faces (sirad image reads them back: scene/ply.h).
  std::string view_comments = fmt::format("comment sirad background {} {} {}\n", mesh.background.x, mesh.background.y, mesh.background.z);
  if (mesh.camera) view_comments += "comment sirad camera " + camera_spec(*mesh.camera) + "\n";
  if (error_estimate >= 0.0 && std::isfinite(error_estimate))
    view_comments += fmt::format("comment sirad error estimate {}\n", error_estimate);
  std::string header = fmt::format(
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment sirad scene hash {}\n"
      "{}"
      "element vertex {}\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "element face {}\n"
      "property list uchar int vertex_indices\n",
      mesh.hash, view_comments, vertex.size(), mesh.size());
  for (const char* quantity : {"radiosity", "reflectance", "emission"})
    for (const char* channel : {"r", "g", "b"})
      header += fmt::format("property float {}_{}\n", quantity, channel);
  const bool gaps = mesh.in_gap.size() == mesh.size();
  if (gaps) header += "property uchar sirad_in_gap\n";  // PatchMesh::in_gap, for corner_radiosity on reading
  header += "end_header\n";

  // Step 4: the body, in chunks: vertices, then one face per patch in patch order.
  AtomicFile file(path);
  file.write(header.data(), header.size());
  std::vector<unsigned char> chunk;
  const auto flush_chunk = [&](std::size_t limit) {
    if (chunk.size() < limit) return;
    file.write(chunk.data(), chunk.size());
    chunk.clear();
  };
  constexpr std::size_t chunk_bytes = 1 << 16;
  for (std::size_t v = 0; v < vertex.size(); ++v) {
    put_le(chunk, mesh.vertices[vertex[v]]);
    for (int k = 0; k < 3; ++k) chunk.push_back(tone_map(value[v][k], scale));
    flush_chunk(chunk_bytes);
  }
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    chunk.push_back(3);
    for (int k = 0; k < 3; ++k) put_le(chunk, static_cast<int32_t>(faces[3 * j + static_cast<std::size_t>(k)]));
    put_le(chunk, radiosity[j]);
    put_le(chunk, mesh.reflectance(j));
    put_le(chunk, mesh.emission(j));
    if (gaps) chunk.push_back(mesh.in_gap[j]);
    flush_chunk(chunk_bytes);
  }
  flush_chunk(0);
  file.commit();
}

}  // namespace sirad
