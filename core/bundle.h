// sirad: one bundle of parallel global lines — its parameters and the engines that run it.
// A bundle is fixed by (run seed, bundle index, stream): Random123 Philox gives its direction
// (uniform on the sphere) and its grid jitter; the host rounds them once into a SiradBundle
// that every engine (OpenCL kernels on any device, the C++ reference) uses unchanged.
#pragma once
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "core/mesh.h"
#include "kernels/bundle_types.h"

static_assert(sizeof(SiradBundle) == 4 * 22, "SiradBundle layout must match bundle_types.h");
static_assert(sizeof(SiradProjected) == 4 * 26, "SiradProjected layout must match bundle_types.h");

namespace sirad {

// Streams of Philox draws: counted bundles, the burn-in of a chain and the first shot's
// samples (core/shot.h) never share one.
enum class Stream : uint32_t { bundles = 0, burn_in = 1, shots = 2, burn_in_shots = 3 };

// The direction and jitter of bundle `index` of a run with `seed` (double precision).
struct BundleDraw {
  glm::dvec3 direction;  // uniform on the unit sphere
  double jitter_x, jitter_y;  // uniform in (0, 1)
};
BundleDraw draw_bundle(uint64_t seed, uint64_t index, Stream stream = Stream::bundles);

// The bundle parameters for `mesh` with an R x R grid. Banding and scratch capacities are the
// engine's: make_bundle leaves one band of all rows and capacities 0.
SiradBundle make_bundle(const PatchMesh& mesh, int grid, uint64_t seed, uint64_t index,
                        Stream stream = Stream::bundles);

// World area of the cell each line stands for: (2 r / (R - 1))^2.
double cell_area(const PatchMesh& mesh, int grid);

// An upper bound on the crossings of any bundle (engines size their scratch from it): per patch, lattice points in a convex region
// <= area + perimeter / 2 + 1 (in cell units), with the projected area and perimeter bounded
// by the patch's own.
uint64_t capacity_bound(const PatchMesh& mesh, int grid);

// A grid that gives the median patch about 4 crossings per bundle (clamped to [32, 2048]).
int auto_grid(const PatchMesh& mesh);

// Vertices relative to the bounding-sphere centre (computed in double, rounded once), as
// every engine projects them.
std::vector<glm::vec4> centred_vertices(const PatchMesh& mesh);

// What one bundle produces: per patch, the sum over the lines crossing it of the radiance of
// its front neighbour (rgb; w unused), and the number of those lines.
struct BundleResult {
  std::vector<glm::vec4> gathered;
  std::vector<uint32_t> hits;
  uint64_t crossings = 0;  // line-patch crossings in the bundle
};

// Runs bundles over one mesh. `radiance` has one value per patch (rgb; w ignored).
class BundleEngine {
 public:
  virtual ~BundleEngine() = default;
  virtual void run(const SiradBundle& bundle, std::span<const glm::vec4> radiance,
                   BundleResult& result) = 0;
  virtual std::string description() const = 0;
};

// The plain, single-threaded C++ reference of one bundle (core/bundle_reference.cpp).
std::unique_ptr<BundleEngine> make_reference_engine(const PatchMesh& mesh);

}  // namespace sirad
