// sirad tests: the outputs (io/write.h, io/results.h): EXR, PNG, PLY, atomic writes, all or none.
#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <gtest/gtest.h>
#include <png.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include "io/results.h"
#include "io/write.h"
#include "render/gather.h"
#include "tests/mesh_builder.h"
#include "tests/png_util.h"
#include "util/error.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;
using test::facing_quad;
using test::inside_box;
using test::MeshBuilder;

// ---- helpers ----

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

bool tool_available(const char* tool) {
  return std::system(fmt::format("command -v {} >/dev/null 2>&1", tool).c_str()) == 0;
}

// A fresh directory per test, removed afterwards.
class OutputFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("sirad_output_test_{}_{}_{}", ::getpid(),
                                                   info->test_suite_name(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string file(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_))
      names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  fs::path dir_;
};

class OutputExr : public OutputFiles {};
class OutputPng : public OutputFiles {};
class OutputPly : public OutputFiles {};
class OutputAtomic : public OutputFiles {};

Image small_image() {
  Image image{5, 3, {}};
  for (int i = 0; i < 15; ++i)
    image.pixels.push_back(glm::vec3(0.1f * i, -2.5f + i, 1e-30f * float(i + 1)));
  image.pixels[7] = glm::vec3(65504.5f, 1e30f, std::numeric_limits<float>::denorm_min());
  return image;
}

// ---- EXR ----

TEST_F(OutputExr, RoundTrip) {
  const Image image = small_image();
  const Attributes attributes{{"sirad.bundles", int64_t{1024}},
                              {"sirad.min_int", int64_t{std::numeric_limits<int32_t>::min()}},
                              {"sirad.big", int64_t{1} << 40},
                              {"sirad.seconds", 1.25},
                              {"sirad.scene", std::string("cornell box")}};
  const std::string path = file("view.exr");
  write_exr(path, image, attributes);
  EXPECT_EQ(listing(), std::vector<std::string>{"view.exr"});

  Imf::InputFile in(path.c_str());
  const Imf::Header& header = in.header();
  EXPECT_EQ(header.compression(), Imf::ZIP_COMPRESSION);
  EXPECT_EQ(header.dataWindow().min.x, 0);
  EXPECT_EQ(header.dataWindow().max.x, image.width - 1);
  EXPECT_EQ(header.dataWindow().max.y, image.height - 1);
  int channel_count = 0;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    ++channel_count;
    EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
  }
  EXPECT_EQ(channel_count, 3);
  for (const char* channel : {"R", "G", "B"})
    EXPECT_NE(header.channels().findChannel(channel), nullptr);

  const auto* bundles = header.findTypedAttribute<Imf::IntAttribute>("sirad.bundles");
  ASSERT_NE(bundles, nullptr);
  EXPECT_EQ(bundles->value(), 1024);
  const auto* min_int = header.findTypedAttribute<Imf::IntAttribute>("sirad.min_int");
  ASSERT_NE(min_int, nullptr);
  EXPECT_EQ(min_int->value(), std::numeric_limits<int32_t>::min());
  const auto* big = header.findTypedAttribute<Imf::DoubleAttribute>("sirad.big");
  ASSERT_NE(big, nullptr);
  EXPECT_EQ(big->value(), 1099511627776.0);
  const auto* seconds = header.findTypedAttribute<Imf::DoubleAttribute>("sirad.seconds");
  ASSERT_NE(seconds, nullptr);
  EXPECT_EQ(seconds->value(), 1.25);
  const auto* scene = header.findTypedAttribute<Imf::StringAttribute>("sirad.scene");
  ASSERT_NE(scene, nullptr);
  EXPECT_EQ(scene->value(), "cornell box");

  std::vector<glm::vec3> pixels(image.pixels.size(), glm::vec3(-7));
  char* base = reinterpret_cast<char*>(pixels.data());
  const std::size_t xs = sizeof(glm::vec3), ys = xs * image.width;
  Imf::FrameBuffer frame;
  frame.insert("R", Imf::Slice(Imf::FLOAT, base, xs, ys));
  frame.insert("G", Imf::Slice(Imf::FLOAT, base + 4, xs, ys));
  frame.insert("B", Imf::Slice(Imf::FLOAT, base + 8, xs, ys));
  in.setFrameBuffer(frame);
  in.readPixels(0, image.height - 1);
  EXPECT_EQ(std::memcmp(pixels.data(), image.pixels.data(), pixels.size() * sizeof(glm::vec3)), 0);

  if (tool_available("exrinfo")) {
    // Its output, not its exit status: Debian's exrinfo 3.1 returns a random status on about
    // one run in six for any file.
    EXPECT_EQ(std::system(fmt::format("exrinfo -s '{}' 2>&1 | grep -q \"channels: 3 channels\"", path).c_str()), 0);
  }
  if (tool_available("exrheader")) {
    EXPECT_EQ(std::system(fmt::format("exrheader '{}' >/dev/null", path).c_str()), 0);
  }
}

TEST_F(OutputExr, RejectsBadImagesAndAttributes) {
  const Image image = small_image();
  const std::string path = file("bad.exr");
  EXPECT_THROW(write_exr(path, Image{}, {}), Error);
  Image short_image = image;
  short_image.pixels.pop_back();
  EXPECT_THROW(write_exr(path, short_image, {}), Error);
  for (const char* name : {"", "compression", "channels", "dataWindow", "owner"})
    EXPECT_THROW(write_exr(path, image, {{name, int64_t{1}}}), Error) << "'" << name << "'";
  EXPECT_THROW(write_exr(path, image, {{std::string(300, 'a'), 1.0}}), Error);
  EXPECT_THROW(write_exr(path, image, {{"sirad.x", 1.0}, {"sirad.x", std::string("y")}}), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- PNG ----

// Reads an 8-bit RGB PNG (it must be one: what write_png writes).
std::vector<unsigned char> read_png(const std::string& path, int& width, int& height) {
  png_uint_32 format = 0;
  std::vector<unsigned char> bytes = sirad::test::read_png(path, width, height, &format);
  EXPECT_EQ(format, static_cast<png_uint_32>(PNG_FORMAT_RGB));
  return bytes;
}

TEST_F(OutputPng, ToneMapAndExposure) {
  const float inf = std::numeric_limits<float>::infinity(),
              nan = std::numeric_limits<float>::quiet_NaN();
  Image image{3,
              2,
              {glm::vec3(0, 1, 0.5f), glm::vec3(nan, inf, -inf), glm::vec3(2, -1, 0.25f),
               glm::vec3(0.001f, 0.5f, 0), glm::vec3(1, 1, 1), glm::vec3(0.25f, 0.5f, 0.125f)}};
  int width = 0, height = 0;
  write_png(file("a.png"), image);
  EXPECT_EQ(read_png(file("a.png"), width, height),
            (std::vector<unsigned char>{0, 255, 188, 0, 255, 0, 255, 0, 137, 3, 188, 0, 255, 255,
                                        255, 137, 188, 99}));
  EXPECT_EQ(width, 3);
  EXPECT_EQ(height, 2);
  write_png(file("b.png"), image, 1.0f);
  EXPECT_EQ(read_png(file("b.png"), width, height),
            (std::vector<unsigned char>{0, 255, 255, 0, 255, 0, 255, 0, 188, 7, 255, 0, 255, 255,
                                        255, 188, 255, 137}));
  EXPECT_EQ(listing(), (std::vector<std::string>{"a.png", "b.png"}));
}

TEST_F(OutputPng, LibpngErrorBecomesSiradError) {
  // Wider than libpng's default limit of 1,000,000 columns: libpng fails in png_set_IHDR.
  Image image{1000001, 1, std::vector<glm::vec3>(1000001, glm::vec3(0.5f))};
  const std::string path = file("wide.png");
  try {
    write_png(path, image);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_png(path, Image{}), Error);
  EXPECT_THROW(write_png(path, small_image(), std::numeric_limits<float>::quiet_NaN()), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- PLY ----

template <typename T>
T get_le(const std::vector<unsigned char>& bytes, std::size_t& at) {
  uint32_t bits = 0;
  for (int i = 0; i < 4; ++i) bits |= uint32_t(bytes.at(at + i)) << (8 * i);
  at += 4;
  return std::bit_cast<T>(bits);
}

TEST_F(OutputPly, HeaderAndBody) {
  MeshBuilder b;
  b.quad({0, 0, 0}, {1.5f, 0, 0}, {1.5f, 2.25f, 0}, {0, 2.25f, -0.125f});
  b.mesh.material[1] = 1;
  const std::vector<glm::vec3> radiosity{glm::vec3(0.1f, 0.2f, 0.3f), glm::vec3(40, 50, 60)};
  const std::string path = file("mesh.ply");
  write_ply(path, b.mesh, radiosity);
  const std::vector<unsigned char> bytes = read_bytes(path);

  const std::string expected_header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment sirad scene hash 0123456789abcdef0123456789abcdef\n"
      "comment sirad background 0 0 0\n"
      "element vertex 6\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "element face 2\n"
      "property list uchar int vertex_indices\n"
      "property float radiosity_r\n"
      "property float radiosity_g\n"
      "property float radiosity_b\n"
      "property float reflectance_r\n"
      "property float reflectance_g\n"
      "property float reflectance_b\n"
      "property float emission_r\n"
      "property float emission_g\n"
      "property float emission_b\n"
      "end_header\n";
  ASSERT_GE(bytes.size(), expected_header.size());
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + expected_header.size()), expected_header);
  // The two patches have different materials: their corners are not shared (6 vertices, not
  // the 4 welded ones), each vertex has its patch's value as the PNG's sRGB bytes.
  ASSERT_EQ(bytes.size(), expected_header.size() + 6 * 15 + 2 * (1 + 12 + 36));
  auto srgb_byte = [](float v) {
    double x = std::clamp(static_cast<double>(v), 0.0, 1.0);
    return static_cast<int>(std::lround(255.0 * (x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055)));
  };
  std::size_t at = expected_header.size();
  for (std::size_t j = 0; j < 2; ++j)
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < 3; ++c) EXPECT_EQ(get_le<float>(bytes, at), b.mesh.vertices[b.mesh.patches[j][k]][c]);
      for (int c = 0; c < 3; ++c) EXPECT_EQ(int(bytes.at(at++)), srgb_byte(radiosity[j][c])) << j << " " << k << " " << c;
    }
  for (std::size_t j = 0; j < 2; ++j) {
    EXPECT_EQ(bytes.at(at++), 3);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(get_le<int32_t>(bytes, at), int32_t(3 * j + k));
    for (const glm::vec3& v : {radiosity[j], b.mesh.reflectance(j), b.mesh.emission(j)})
      for (int c = 0; c < 3; ++c) EXPECT_EQ(get_le<float>(bytes, at), v[c]);
  }
  EXPECT_EQ(at, bytes.size());
}

TEST_F(OutputPly, RejectsMismatchedRadiosity) {
  EXPECT_THROW(write_ply(file("mesh.ply"), facing_quad(), {glm::vec3(1)}), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- atomic writes ----

TEST_F(OutputAtomic, MissingDirectoryThrowsAndLeavesNothing) {
  const Image image = small_image();
  const PatchMesh quad = facing_quad();
  const std::vector<glm::vec3> radiosity{glm::vec3(1), glm::vec3(3)};
  const std::string exr = file("missing/x.exr"), png = file("missing/x.png"),
                    ply = file("missing/x.ply");
  for (const auto& [path, write] :
       {std::pair<std::string, std::function<void()>>{exr, [&] { write_exr(exr, image, {}); }},
        {png, [&] { write_png(png, image); }},
        {ply, [&] { write_ply(ply, quad, radiosity); }}}) {
    try {
      write();
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()),
                fmt::format("cannot write {}: No such file or directory", path));
    }
  }
  EXPECT_TRUE(listing().empty());
}

TEST_F(OutputAtomic, ReplacesExistingFiles) {
  const Image image = small_image();
  const PatchMesh quad = facing_quad();
  for (const char* name : {"x.exr", "x.png", "x.ply"}) std::ofstream(file(name)) << "old contents";
  write_exr(file("x.exr"), image, {});
  write_png(file("x.png"), image);
  write_ply(file("x.ply"), quad, {glm::vec3(1), glm::vec3(3)});
  EXPECT_EQ(listing(), (std::vector<std::string>{"x.exr", "x.ply", "x.png"}));
  const auto exr = read_bytes(file("x.exr"));
  ASSERT_GE(exr.size(), 4u);
  EXPECT_EQ(std::vector<unsigned char>(exr.begin(), exr.begin() + 4),
            (std::vector<unsigned char>{0x76, 0x2f, 0x31, 0x01}));
  int width = 0, height = 0;
  EXPECT_EQ(read_png(file("x.png"), width, height).size(), image.pixels.size() * 3);
  const auto ply = read_bytes(file("x.ply"));
  EXPECT_EQ(std::string(ply.begin(), ply.begin() + 4), "ply\n");
}

// Limits the size of files this process may write (RLIMIT_FSIZE, with SIGXFSZ ignored so a write
// past it fails with EFBIG) while in scope.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    saved_handler_ = signal(SIGXFSZ, SIG_IGN);
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    signal(SIGXFSZ, saved_handler_);
  }

 private:
  rlimit saved_{};
  sighandler_t saved_handler_;
};

TEST_F(OutputAtomic, WriteFailureThrowsAndLeavesNothing) {
  // Incompressible content, far larger than the limit: the writes fail part way.
  std::mt19937 rng(3);
  Image noise{200, 200, {}};
  for (int i = 0; i < 200 * 200; ++i)
    noise.pixels.push_back(glm::vec3(float(rng()) / 4294967296.0f, float(rng()) / 4294967296.0f,
                                     float(rng()) / 4294967296.0f));
  const auto [box, radiosity] = inside_box(20);
  const std::string exr = file("x.exr"), png = file("x.png"), ply = file("x.ply");
  {
    const FileSizeLimit limit(10000);
    for (const auto& [path, write] :
         {std::pair<std::string, std::function<void()>>{exr, [&] { write_exr(exr, noise, {}); }},
          {png, [&] { write_png(png, noise); }},
          {ply, [&] { write_ply(ply, box, radiosity); }}}) {
      try {
        write();
        ADD_FAILURE() << "no error for " << path;
      } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), fmt::format("cannot write {}: File too large", path));
      }
    }
  }
  {
    // A small EXR stays in the stdio buffer until OpenEXR seeks back to write its line offsets
    // (in OutputFile's destructor, which swallows errors): the failure must still surface.
    const FileSizeLimit limit(300);
    try {
      write_exr(exr, small_image(), {});
      ADD_FAILURE() << "no error for the small EXR";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), fmt::format("cannot write {}: File too large", exr));
    }
  }
  EXPECT_TRUE(listing().empty());
}

TEST_F(OutputAtomic, FailedRenameRemovesTemporary) {
  // The target is a directory: the temporary is complete but cannot be renamed onto it.
  fs::create_directory(file("target"));
  const Image image = small_image();
  EXPECT_THROW(write_exr(file("target"), image, {}), Error);
  EXPECT_THROW(write_png(file("target"), image), Error);
  EXPECT_THROW(write_ply(file("target"), facing_quad(), {glm::vec3(1), glm::vec3(3)}), Error);
  EXPECT_EQ(listing(), std::vector<std::string>{"target"});
  EXPECT_TRUE(fs::is_empty(file("target")));
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

class OutputResults : public OutputFiles {
 protected:
  PatchMesh quad_with_camera() const {
    PatchMesh m = facing_quad();
    m.camera = Camera{glm::vec3(0, 0, 3), glm::vec3(0), glm::vec3(0, 1, 0), 60.0f};
    return m;
  }
  ResultOptions small() const {
    ResultOptions o;
    o.width = 8;
    o.height = 8;
    return o;
  }
};

// The four outputs are all replaced or none is: with a directory where the PLY goes, the old
// EXR, PNG and glTF stay as they were, and no temporary is left.
TEST_F(OutputResults, AllOrNone) {
  for (const char* name : {"x.exr", "x.png", "x.glb"}) std::ofstream(file(name)) << "old contents";
  fs::create_directory(file("x.ply"));
  EXPECT_THROW(write_results(file("x"), quad_with_camera(), {glm::vec3(1), glm::vec3(3)}, small(), {}), Error);
  EXPECT_EQ(listing(), (std::vector<std::string>{"x.exr", "x.glb", "x.ply", "x.png"}));
  for (const char* name : {"x.exr", "x.png", "x.glb"}) {
    std::ifstream in(file(name));
    std::string text((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(text, "old contents") << name;
  }
  fs::remove(file("x.ply"));
  write_results(file("x"), quad_with_camera(), {glm::vec3(1), glm::vec3(3)}, small(), {});
  EXPECT_EQ(listing(), (std::vector<std::string>{"x.exr", "x.glb", "x.ply", "x.png"}));
}

// A result with a non-finite value is never written (it used to give an all-NaN PLY and exit 0).
TEST_F(OutputResults, NonFiniteResultIsNeverWritten) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  try {
    write_results(file("x"), quad_with_camera(), {glm::vec3(1), glm::vec3(1, nan, 1)}, small(), {});
    ADD_FAILURE() << "written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not finite at patch 1"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(listing().empty());
}

// A solution outlives its image (issue 35): where the final gather could not render the view (a
// camera 1e20 away, past check_camera_reach), or the image failed elsewhere (a cluster run's
// RunResult::image_error), the PLY and glb are still written and the error says so; no EXR or
// PNG is.
TEST_F(OutputResults, TheSolutionIsKeptWhenItsImageFails) {
  PatchMesh far = quad_with_camera();
  far.camera->eye = glm::vec3(0, 0, 1e20f);
  ResultOptions gather = small();
  gather.final_gather_spp = 4;
  // The far camera's failure as the final gather gives it (cli write_outputs hands it on).
  std::string far_failed;
  try {
    FinalGather(far, {glm::vec3(1), glm::vec3(3)}, final_gather_of(gather)).render(*far.camera);
  } catch (const Error& e) {
    far_failed = e.what();
  }
  for (const auto& [mesh, failed, why] : {std::tuple{far, far_failed, std::string("the camera's eye is 1e+20")},
                                          std::tuple{quad_with_camera(), std::string("tile 3 was lost"), std::string("tile 3 was lost")}}) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    try {
      write_results(file("x"), mesh, {glm::vec3(1), glm::vec3(3)}, gather, {}, nullptr, failed);
      ADD_FAILURE() << "no error for " << why;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("no image ("), std::string::npos) << what;
      EXPECT_NE(what.find(why), std::string::npos) << what;
      EXPECT_NE(what.find("the solution is kept in " + file("x.ply") + " and " + file("x.glb")), std::string::npos) << what;
    }
    EXPECT_EQ(listing(), (std::vector<std::string>{"x.glb", "x.ply"})) << why;
    std::ifstream ply(file("x.ply"));
    std::string text((std::istreambuf_iterator<char>(ply)), {});
    EXPECT_EQ(text.rfind("ply\n", 0), 0u) << why;
  }
}

// An output name that is a directory (`--out some/dir/`) is refused before the run.
TEST_F(OutputResults, ADirectoryIsNotAnOutputName) {
  EXPECT_THROW(check_output_name(dir_.string() + "/", "--out"), Error);
  EXPECT_NO_THROW(check_output_name(file("x"), "--out"));
}

}  // namespace
}  // namespace sirad
