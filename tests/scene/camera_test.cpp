// sirad tests: the camera convention (scene/camera.h): a square's edges on pixel boundaries
// cover whole pixels, in the rasteriser and in the final gather.
#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include "io/write.h"
#include "render/gather.h"
#include "render/image.h"
#include "scene/camera.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "tests/quad_scene.h"

namespace sirad {
namespace {

using test::QuadScene;

// The camera convention (scene/camera.h): 16 x 16 pixels, a 90 degree field of view, the eye at
// the origin looking along +z with up +y, so right = forward x up = -x. A square emitter 1 unit in
// front of the eye spans world x in [-0.25, 0.5] (camera x in [-0.5, 0.25]) and y in [-0.25, 0.5].
// On the image plane at distance 1 a pixel is 2 / 16 = 0.125 wide, so the square's edges fall
// exactly on raster x = (x_cam + 1) / 2 * 16 = 4 and 10 and y = (1 - y) / 2 * 16 = 4 and 10: pixels 4..9
// both ways see the emitter in every sample (value E = 1, exactly), every other pixel sees the
// background (0) in every sample. A framing off by a fraction of a pixel (pixel corners taken for
// centres, say) leaves the edge pixels partly covered, between 0 and 1. The rasteriser (4 x 4
// samples per pixel) and the final gather (16 jittered samples) both follow it.
TEST(Camera, EdgesOnPixelBoundariesCoverWholePixels) {
  QuadScene q;
  const uint32_t light = q.material(glm::vec3(0.0f), glm::vec3(1.0f));
  q.quad({0.5f, -0.25f, 1}, {-0.25f, -0.25f, 1}, {-0.25f, 0.5f, 1}, {0.5f, 0.5f, 1}, light);  // faces -z: the eye
  PatchMesh mesh = mesh_scene(q.scene, MeshOptions{});
  const Camera camera{{0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 90.0f};
  const std::vector<glm::vec3> radiosity(mesh.size(), glm::vec3(1.0f));
  GatherOptions o{.width = 16, .height = 16, .spp = 16, .threads = 1};
  const Image gathered = FinalGather(mesh, radiosity, o).render(camera).combined;
  const Image drawn = render_view_antialiased(mesh, radiosity, camera, 16, 16, Shading::flat, 4);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      const float want = x >= 4 && x < 10 && y >= 4 && y < 10 ? 1.0f : 0.0f;
      EXPECT_EQ(gathered.at(x, y).x, want) << "final gather, pixel " << x << ", " << y;
      EXPECT_EQ(drawn.at(x, y).x, want) << "rasteriser, pixel " << x << ", " << y;
    }
  // The raster position of a camera-space point and the direction through a raster point invert.
  const CameraFrame f = camera_frame(camera, 16, 16);
  const auto [rx, ry] = f.raster(-0.5, 0.5, 1.0);
  EXPECT_DOUBLE_EQ(rx, 4.0);
  EXPECT_DOUBLE_EQ(ry, 4.0);
  const glm::dvec3 d = f.direction(10.0, 10.0);
  EXPECT_NEAR(d.x / d.z, -0.25, 1e-12);  // world x: right is -x
  EXPECT_NEAR(d.y / d.z, -0.25, 1e-12);
}

}  // namespace
}  // namespace sirad
