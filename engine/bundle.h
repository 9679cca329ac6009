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

#include "kernels/bundle_types.h"
#include "scene/mesh.h"

static_assert(sizeof(SiradBundle) == 4 * 22, "SiradBundle layout must match bundle_types.h");
static_assert(sizeof(SiradProjected) == 4 * 26, "SiradProjected layout must match bundle_types.h");

namespace sirad {

// Streams of Philox draws: counted bundles, the burn-in of a chain, the first shot's samples
// (engine/shot.h) and the model fit's bundles (model/model_fit.h) never share one.
enum class Stream : uint32_t { bundles = 0, burn_in = 1, shots = 2, burn_in_shots = 3, fit = 4 };

// How a run draws its bundles' directions and jitters (DESIGN.md section 1, lever 2).
//   random      every bundle independent: direction uniform on the sphere, jitter uniform.
//   stratified  the counted bundles form G interleaved sequences (index k belongs to sequence
//               k mod G); sequence s visits, in blocks of K = n x n consecutive members, the K
//               equal-area strata of the hemisphere (concentric square-to-disk map, then the
//               Lambert lift) in a random order keyed by (seed, stream, s, block), each bundle
//               uniform inside its stratum with a random sign (w and -w are the same lines);
//               the jitter is stratified the same way over the cell with an independent order.
//               Every bundle's direction is uniform on the sphere and its jitter uniform in the
//               cell, so each transport stays unbiased; bundles of one (sequence, block) are
//               dependent, and those are >= G apart in index. Burn-in bundles stay random.
// Bias analysis and the choice of G and K: engine/bundle.cpp, above sampling_plan.
enum class Directions { random, stratified };
Directions parse_directions(const std::string& name);  // "random" | "stratified"
const char* to_string(Directions directions);

struct Sampling {
  Directions directions = Directions::random;
  uint32_t interleave = 1;  // G (stratified): sequences interleaved by index mod G, 1..256
  uint32_t side = 16;       // n (stratified): K = n * n strata per block, 1..64
};

// The sampling of a run on `mesh`: for stratified, G = the smallest G with rho_max^G <= 1e-3
// (1 for a scene that reflects nothing, at most 256) and n = 16 (K = 256).
Sampling sampling_plan(const PatchMesh& mesh, Directions directions);

// The direction and jitter of bundle `index` of a run with `seed` (double precision): a pure
// function of (seed, index, stream, sampling), whichever node draws it.
struct BundleDraw {
  glm::dvec3 direction;  // uniform on the unit sphere
  double jitter_x, jitter_y;  // uniform in (0, 1)
};
BundleDraw draw_bundle(uint64_t seed, uint64_t index, Stream stream = Stream::bundles,
                       const Sampling& sampling = {});

// The strata of a stratified bundle (for tests): its position in the block's order visits
// direction stratum `direction` and jitter stratum `jitter` (both in [0, K)); the block is
// (sequence, block). Random sampling: all zero.
struct StratumOf {
  uint32_t direction = 0, jitter = 0;
  uint64_t sequence = 0, block = 0;
};
StratumOf stratum_of(uint64_t seed, uint64_t index, Stream stream, const Sampling& sampling);

// `orders` independent uniform random permutations of 0..k-1, concatenated: a pure function of
// (seed, block, tag). Tags keep different users' draws apart: bundle strata use 0x4000xxxx,
// shot strata 0x6000xxxx (engine/shot.cpp), bundle draws themselves only small word-2 values.
std::vector<uint32_t> block_orders(uint64_t seed, uint64_t block, uint32_t tag, uint32_t k, uint32_t orders);

// The bundle parameters for `mesh` with an R x R grid. Banding and scratch capacities are the
// engine's: make_bundle leaves one band of all rows and capacities 0.
SiradBundle make_bundle(const PatchMesh& mesh, int grid, uint64_t seed, uint64_t index,
                        Stream stream = Stream::bundles, const Sampling& sampling = {});

// World area of the cell each line stands for: (2 r / (R - 1))^2.
double cell_area(const PatchMesh& mesh, int grid);

// An upper bound on the crossings of any bundle (engines size their scratch from it): per patch, lattice points in a convex region
// <= area + perimeter / 2 + 1 (in cell units), with the projected area and perimeter bounded
// by the patch's own.
uint64_t capacity_bound(const PatchMesh& mesh, int grid);
// An upper bound on the (patch, row) spans of any bundle: a patch reaches at most its projected
// height in rows plus one, and its projected height is at most half its perimeter (in cells).
uint64_t span_bound(const PatchMesh& mesh, int grid);

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
  // Runs every bundle of `bundles` over the same radiance: results[k] is what run(bundles[k],
  // radiance, results[k]) gives, bit for bit. The bundles share one grid. Engines that launch
  // several bundles at once (the OpenCL wide path) override it; the others run them in turn.
  virtual void run_batch(std::span<const SiradBundle> bundles, std::span<const glm::vec4> radiance,
                         std::span<BundleResult> results);
  virtual std::string description() const = 0;
  // The bundles a run_batch should hold for this engine to run at its speed (1: one at a time).
  virtual uint32_t preferred_batch() const { return 1; }
};

// The plain, single-threaded C++ reference of one bundle (engine/bundle_reference.cpp).
std::unique_ptr<BundleEngine> make_reference_engine(const PatchMesh& mesh);

}  // namespace sirad
