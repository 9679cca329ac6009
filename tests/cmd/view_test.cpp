// sirad tests: `sirad view` (farm/view_server.h) in a real browser: headless Chromium draws the
// page (three.js from web/node_modules, embedded) from a baked glb's own camera, and the picture
// agrees with `sirad image` of the same solution; the command's refusals.
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "farm/view_server.h"
#include "tests/cli_fixture.h"
#include "tests/png_util.h"
#include "tests/process_util.h"

namespace sirad::test {
namespace {

using Viewer = Cli;

// The first line of `log` that holds `what`, once `writer` has written it ("" if it exited
// first). Waits for the line, bounded only by kHangS.
std::string wait_for_line(const fs::path& log, Child& writer, const std::string& what) {
  auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(kHangS);
  while (std::chrono::steady_clock::now() < until) {
    std::ifstream in(log);
    for (std::string line; std::getline(in, line);)
      if (line.find(what) != std::string::npos) return line;
    if (writer.wait(0.02) >= 0) return "";
  }
  return "";
}

double linear(unsigned char v) {
  const double c = v / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// The Cornell box baked (16 samples a texel, its chart cache), shown by the page at 64 x 64 from
// the glb's camera, against `sirad image` of the same solution (64 spp, the same view and size),
// in linear light, the light's own pixels (saturated in the image) left out. Measured: the
// means agree to 0.5 %, and 8 x 8 blocks to a few per cent but at the open front's floor edge
// and beside the light (up to 33 %: the page draws without anti-aliasing, texels filtered at a
// chart's border). So: the means within 3 % (the image's own noise is about 3 % a pixel, 0.05 %
// over the picture; the rest is the bake's, a few per cent a texel, and the edges'), and 3 of 4
// blocks within 10 %. A page that showed nothing, the wrong camera, or unlit or doubly lit
// materials fails by far.
TEST_F(Viewer, TheBakeInTheBrowserAgreesWithSiradImage) {
  const std::string chromium = on_path("chromium");
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (deploy/install-deps.sh installs it)";
  if (!viewer_available()) GTEST_SKIP() << "sirad was built without three.js (deploy/install-deps.sh runs npm ci in web/)";
  Outcome r = sirad("bake cornell --patches 2000 --bundles 200 --width 64 --height 64 --texels 65536 --texel-samples 16 -q --out c");
  ASSERT_EQ(r.status, 0) << r.err;
  r = sirad("image c.ply --spp 64 --width 64 --height 64 -q --out ref");
  ASSERT_EQ(r.status, 0) << r.err;
  Child view({SIRAD_BINARY, "view", (dir_ / "c-baked.glb").string(), "--port", "0"}, dir_ / "view.log");
  const std::string line = wait_for_line(dir_ / "view.log", view, "http://");
  ASSERT_FALSE(line.empty()) << slurp((dir_ / "view.log").string());
  const std::string url = line.substr(line.find("http://"), line.find('/', line.find("http://") + 7) + 1 - line.find("http://"));
  Child shot({chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars",
              "--user-data-dir=" + (dir_ / "profile").string(), "--window-size=64,64", "--virtual-time-budget=30000",
              "--screenshot=" + (dir_ / "shot.png").string(), url + "?probe=1"},
             dir_ / "chromium.log");
  ASSERT_EQ(shot.wait(kHangS), 0) << slurp((dir_ / "chromium.log").string());
  int w = 0, h = 0, rw = 0, rh = 0;
  const std::vector<unsigned char> page = read_png((dir_ / "shot.png").string(), w, h);
  const std::vector<unsigned char> image = read_png((dir_ / "ref.png").string(), rw, rh);
  ASSERT_EQ(w, 64);
  ASSERT_EQ(h, 64);
  ASSERT_EQ(rw, 64);
  ASSERT_EQ(rh, 64);
  double page_sum = 0, image_sum = 0;
  int blocks = 0, near = 0;
  for (int by = 0; by < 64; by += 8)
    for (int bx = 0; bx < 64; bx += 8) {
      double a = 0, b = 0;
      for (int y = by; y < by + 8; ++y)
        for (int x = bx; x < bx + 8; ++x) {
          const std::size_t i = 3 * (static_cast<std::size_t>(y) * 64 + x);
          if (std::max({image[i], image[i + 1], image[i + 2]}) >= 250) continue;  // the light
          for (int c = 0; c < 3; ++c) a += linear(page[i + c]), b += linear(image[i + c]);
        }
      page_sum += a, image_sum += b;
      if (b > 0) ++blocks, near += std::abs(a / b - 1) <= 0.10;
    }
  ASSERT_GT(image_sum, 0.0);
  EXPECT_NEAR(page_sum / image_sum, 1.0, 0.03);
  EXPECT_GE(4 * near, 3 * blocks) << near << " of " << blocks << " blocks within 10 %";
  view.terminate();
  EXPECT_EQ(view.wait(kHangS), 0) << "sirad view did not stop on SIGTERM";
}

TEST_F(Viewer, WhatIsNoGlbIsRefusedInOneLine) {
  write("scene.glb", "not a glb at all");
  expect_error(sirad("view scene.glb"), "not a binary glTF");
  expect_error(sirad("view missing.glb"), "no such file");
}

}  // namespace
}  // namespace sirad::test
