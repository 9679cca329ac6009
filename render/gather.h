// sirad: the final gather, an image of a solved scene as good as a path tracer's. The radiosity
// solution is view-independent; per pixel this traces what the mesh cannot show:
//   - primary visibility per sample, at jittered positions inside the pixel (scene/camera.h);
//   - the direct light, by sampling points on the emitters with shadow rays, combined
//     by multiple importance sampling (balance heuristic) with the cosine-distributed gather
//     ray that hits an emitter; the emitters are sampled as the lights their patches make
//     (scene/emitters.h: a light cut into patches is one triangle or parallelogram), so that a
//     pixel's stratified emitter points are one per cell of the light and penumbrae are quiet;
//     among many lights, a pixel's samples choose one in proportion to an estimate of what it
//     sends to the pixel's first hit (distance, cosines, power), mixed with a quarter by area so
//     that every light keeps a chance (the gather ray that meets a light is weighed by the same
//     choice's pdf);
//   - the indirect light, from cosine-distributed gather rays that look up the solved radiosity
//     where they land, interpolated over the surface (the corner radiosities of io/write.h,
//     barycentric), less the patch's emission: the reflected part Y = B - E only, so the light of
//     the emitters is counted once, by the direct estimate. Where a gather ray lands closer than
//     four patch sizes (a corner, a contact) the light reflected there is traced one bounce
//     further instead.
// The indirect light comes from an irradiance cache of the view (Ward's, on a grid of the image;
// GatherOptions::cache): records of the indirect light at raster points of a grid 16 pixels
// apart, each from 4 x spp gather rays (256 to 16,384), the grid refined down to 2 pixels where
// the corners of a block are not one surface or their indirect light differs more than twofold
// (beside a lamp just under a ceiling), and down to 4 where they lie further apart than a
// quarter of the distance to what reflects light to them; a block of 4 pixels or fewer is taken
// only if its corners of one surface see each other (a thin wall between two corners on one
// floor: no light carried through it); a sample takes its block's corners bilinearly, and
// gathers for itself where none is of its surface. At an edge (a block of 2 pixels whose corners
// are not one surface) a sample takes the corners of its own surface below 256 spp; from 256 spp
// on it gathers for itself (the corners lie up to 2 pixels off, and towards a concave edge the
// indirect light changes fast), and from 256 spp every sample that gathers for itself in a
// cached render traces 8 gather rays, as quiet as the cache's pixels. Then the direct light is the
// emitter sample alone, without MIS against a gather ray, except near large or many emitters (where a
// block's records met emitters with more than 2 % of their rays: its samples still trace a
// gather ray for the MIS). The cache trades the gather ray's noise for a bias where the indirect
// light bends within a block (bench/RESULTS.md: measured per region); without it each sample
// traces one gather ray, as a path tracer's first bounce.
// In radiance units, as the solver (DESIGN.md section 1). What a ray sees follows the solver's
// rule (scene/rays.h RayScene::seen): the front face it meets first, the background when it
// meets a back face first or leaves the scene; coincident faces as in the bundles.
//
// A pixel's value depends only on the seed, the view and the pixel's position (a cache record
// only on the seed, the view and its raster point, whichever thread, tile or node makes it): any
// split of the image into regions (tiles), on any number of threads or nodes, gives the same
// image bit for bit.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/ext/vector_double3.hpp>

#include "render/image.h"
#include "scene/mesh.h"
#include "scene/scene.h"

namespace sirad {

struct GatherOptions {
  int width = 512, height = 512;
  // Samples per pixel: each a jittered primary ray, one emitter sample with its shadow ray and
  // (where it takes nothing from the cache) one gather ray, 8 with the cache from 256 spp on.
  // 1..65536.
  int spp = 64;
  uint64_t seed = 1;
  int threads = 0;  // 0: every core
  // The indirect light from an irradiance cache of the view (above), or (false) from each
  // sample's own gather ray.
  bool cache = true;
  // The threads a render starts at most: `threads`, or every core (0).
  int thread_count() const;
};

// The passes compositors expect, in linear radiance: `direct` is what the camera sees emitted
// (an emitter's E, the background) plus the light reflected straight from the emitters;
// `indirect` the light reflected from everything else (and from the background); `combined`
// their sum.
struct GatherPasses {
  Image direct, indirect, combined;
  uint64_t rays = 0;         // rays cast by the pixels' samples (primary, shadow, gather)
  uint64_t record_rays = 0;  // and for the cache records this render made
  // Passes of width x height, every pixel 0.
  static GatherPasses of_size(int width, int height);
  // The EXR layers (write_exr_layers): the combined unprefixed, then "direct" and "indirect".
  std::vector<std::pair<std::string, const Image*>> layers() const {
    return {{"", &combined}, {"direct", &direct}, {"indirect", &indirect}};
  }
};

class FinalGather {
 public:
  // `radiosity`: the solution, one value per patch of `mesh` (which must outlive this). The
  // scene's rays and the interpolated solution are made here, once for every view rendered.
  // Throws sirad::Error for a solution or options that do not fit (a size mismatch, spp or
  // image size out of range).
  FinalGather(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity, const GatherOptions& options);
  // The same from the solution as interpolated (io/write.h corner_radiosity: 3 values per
  // patch), as a stored solution's glTF holds it.
  FinalGather(const PatchMesh& mesh, std::vector<std::array<glm::vec3, 3>> corners, const GatherOptions& options);
  ~FinalGather();
  FinalGather(const FinalGather&) = delete;
  FinalGather& operator=(const FinalGather&) = delete;

  // The pixels [x0, x1) x [y0, y1) of the view from `camera`: passes of the region's size (its
  // pixel (0, 0) is the image's (x0, y0)), in tiles of 16 x 16 pixels spread over
  // options.threads threads, one of them the caller's. `between`, if given, is called on the
  // caller's thread after each row of a tile it renders (a node's heartbeat). Throws
  // sirad::Error for a region not within the image or a camera that defines no view.
  GatherPasses render(const Camera& camera, int x0, int y0, int x1, int y1, const std::function<void()>& between = nullptr) const;
  // The whole image of the view from `camera`.
  GatherPasses render(const Camera& camera) const;

  const GatherOptions& options() const;

  // A point on a front of the scene (a texel's sample): where, its surface's normal, reflectance
  // and emission.
  struct SurfacePoint {
    glm::dvec3 x{0.0}, normal{0.0}, rho{0.0}, emission{0.0};
  };
  // The light leaving `points`, their mean, as a pixel's samples give it without the cache:
  // per point its emission, `lights` (1..64) emitter samples with their shadow rays and one
  // gather ray, weighed against each other by the balance heuristic with those counts (the
  // emitter points and gather directions stratified over the points, in their order; the light
  // chosen as for a pixel whose first hit is the first point), in the passes' split: `direct`
  // the emission and the light reflected straight from the emitters, `indirect` the rest. It
  // depends only on the seed, `key` (a texel's index), `lights` and the points. Rays cast into
  // `cast`. Without `indirect_too` (a texel whose indirect light comes from elsewhere: the
  // bake's chart cache) `indirect` is 0 and `direct` the same to the bit, for fewer rays: the
  // gather rays only look for emitters, and no bounce is traced further where one lands near.
  void leaving(const std::vector<SurfacePoint>& points, uint64_t key, glm::dvec3& direct, glm::dvec3& indirect,
               uint64_t& cast, int lights = 1, bool indirect_too = true) const;
  // The light arriving at point x of a front facing n from everything but the emitters (what a
  // pixel's indirect pass reflects, before the reflectance), as the cache's records take it: the
  // mean over `rays` (2..65536) stratified cosine gather rays from the streams of `key`. Into
  // `error` the estimate of its standard error (its rays as two interleaved halves, as
  // render/bake.h says), into `nearest` the least distance a ray went.
  glm::dvec3 arriving(const glm::dvec3& x, const glm::dvec3& n, int rays, uint64_t key, glm::dvec3& error, double& nearest,
                      uint64_t& cast) const;
  // Whether nothing stands between points a and b of a surface facing n (the segment lifted off
  // it by the rays' offset): a wall standing between two points of one floor.
  bool in_sight(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& n) const;
  // Whether point x of a front facing n lies inside a solid: the first face met along n, and
  // along each of four directions 60 degrees from it, is met from behind (a floor under a wall
  // standing on it; not one under a one-sided table top, which rays beside it pass).
  bool enclosed(const glm::dvec3& x, const glm::dvec3& n) const;
  // Whether point x of a face of object `object` facing n lies under a face of another object
  // at the same place facing the same way, on top of it by the coincident-face rule (a floor
  // under a rug laid on it at zero gap: the solve gives it no light). Faces of one object at one
  // place are not told apart (none is covered).
  bool covered(const glm::dvec3& x, const glm::dvec3& n, uint32_t object) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sirad
