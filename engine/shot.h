// sirad: the first shot (DESIGN.md section 1, lever 1): the direct light D = rho F E computed
// by shooting from the emitters, so that the stochastic iteration only carries the indirect
// part, Y = D + rho F Y, B = E + Y.
//
// Shot k of a run is fixed by (seed, k): Philox picks an emitter patch L with probability
// p_L proportional to its power A_L (E_r + E_g + E_b), a uniform point y on it, a rotation of
// the hemicube about its normal and a jitter of the pixel lattice. An engine renders the
// hemicube from y (which patch each pixel sample sees, front faces only); the host adds, per
// receiving patch j,
//     D_j += rho_j E_L A_L / (p_L A_j) * sum over j's pixel samples of dF,
//     dF = max(0, d.n) h^2 / (pi |d|^4)   (d: the sample's direction on its face, h = 2 / H),
// an unbiased estimate of rho_j sum_L F_jL E_L by reciprocity (A_j F_jL = integral over L of
// the point-to-patch form factor F(y -> j)), because the jittered samples make sum dF an
// unbiased estimate of F(y -> j) and y is uniform on L.
#pragma once
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "engine/bundle.h"
#include "kernels/shot_types.h"
#include "scene/mesh.h"

static_assert(sizeof(SiradShot) == 4 * 58, "SiradShot layout must match shot_types.h");

namespace sirad {

// The emitters of a mesh and the probability of shooting from each.
struct EmitterTable {
  std::vector<uint32_t> patch;   // emitting patches
  std::vector<double> cdf;       // cumulative p_L, cdf.back() == 1
  std::vector<double> p;         // p_L
  bool empty() const { return patch.empty(); }
};
EmitterTable emitter_table(const PatchMesh& mesh);
// The emitters a run shoots from (DESIGN.md section 1, "Which emitters the shot takes"): the
// emitting patches of the lights (scene/emitters.h) that their receivers see coherently. A shot
// estimates every receiver x from one point y of the light, so it is as good as the kernel
// K(y, x) = cos_y cos_x V(y, x) / r^2 is flat over y. Per light, kIncoherenceRays cosine rays
// from points y1 find receivers x as the light's power reaches them, a second point y2 is drawn,
// and the incoherence is the mean of (K2 - K1)^2 / (K1^2 + K2^2): 0 where x sees the whole light
// alike (a far, unoccluded receiver), near 1 where it sees only part of it (the ceiling 1.5 cm
// above a lamp's upper side, lit almost only from the point under it; a room seen from a sky
// plane through a window). Lights above kShotIncoherence are left to the bundles' lines, which
// sample (x, y) pairs independently; their emission stays in what the bundles carry, which keeps
// the estimate unbiased for any split (solver/solver.cpp). Deterministic. `incoherence`, if given,
// gets each light's value, in find_lights' order (1 for a light that lights nothing).
inline constexpr double kShotIncoherence = 0.25;
inline constexpr int kIncoherenceRays = 512;
EmitterTable shot_emitter_table(const PatchMesh& mesh, std::vector<double>* incoherence = nullptr);

// One shot's draw (double precision) and its view as engines render it.
struct ShotDraw {
  std::size_t emitter = 0;  // index into EmitterTable::patch
  glm::dvec3 eye{0.0};      // world point on the emitter
  glm::dvec3 axes[5][3];    // per face a, b, c (c: where it looks)
  double jitter_x = 0.5, jitter_y = 0.5;  // of the pixel lattice, in (0, 1)
};
// `stratified`: the shots form blocks of kShotStrata consecutive indices; a block visits the
// n x n strata (n = 8) of the unit square in a random order keyed by (seed, stream, block), and
// the stratum's point (u, v) picks the emitter by inverting the power CDF at u, the point in
// it from u's remainder inside the emitter's CDF step and v: each shot is still uniform over
// the emitters' power marginally (so each shot's estimate stays unbiased), and a block of
// shots covers the lights evenly. Shots only enter the solver linearly and independently of
// the bundles' directions, so their dependence within a block biases nothing (solver/solver.cpp).
inline constexpr uint32_t kShotStrataSide = 8, kShotStrata = kShotStrataSide * kShotStrataSide;
ShotDraw draw_shot(const PatchMesh& mesh, const EmitterTable& table, uint64_t seed, uint64_t index,
                   Stream stream = Stream::shots, bool stratified = false);
SiradShot make_shot(const PatchMesh& mesh, const ShotDraw& draw, int resolution);

// Pixel samples of a shot's image (face 0: H x H, faces 1..4: H/2 x H) and the index of face
// f's row y, column x in it.
std::size_t shot_pixels(int resolution);
std::size_t shot_pixel(int resolution, int face, int y, int x);

// Renders shots: which patch each pixel sample sees (SIRAD_NO_PATCH: none, or a back face).
class ShotEngine {
 public:
  virtual ~ShotEngine() = default;
  virtual void render(const SiradShot& shot, std::vector<uint32_t>& image) = 0;
  virtual std::string description() const = 0;
};

// The plain C++ reference: a ray per pixel sample against every patch (double precision,
// Moller-Trumbore), written for tests. `ambiguous` (optional) marks the samples whose ray
// passes within `edge_eps` (in pixel units) of an edge of a patch it might hit, or whose two
// nearest hits are within the depth tie: where two exact methods may differ.
std::unique_ptr<ShotEngine> make_reference_shot_engine(const PatchMesh& mesh);
void reference_shot_ambiguity(const PatchMesh& mesh, const SiradShot& shot, double edge_eps,
                              std::vector<uint8_t>& ambiguous);

// The OpenCL engine (kernels/shot.cl) on the device `device` names (see select_device),
// projecting and rasterising `block` patches at a time (0: its own block size, 131072; the
// image does not depend on it).
std::unique_ptr<ShotEngine> make_cl_shot_engine(const PatchMesh& mesh, const std::string& device = {}, std::size_t block = 0);

// The per-pixel form-factor weights dF of a shot (double), in image order.
std::vector<double> shot_weights(const SiradShot& shot);
void shot_weights(const SiradShot& shot, std::vector<double>& out);  // into out (resized)

// Shots [first, first + count) of a run: the sum over them of each patch's estimate of D
// (divide by the number of shots for the estimate). Emission-free meshes give zeros.
struct ShotSums {
  std::vector<glm::dvec3> direct;  // per patch, summed over the shots
  uint64_t shots = 0;
};
ShotSums run_shots(const PatchMesh& mesh, ShotEngine& engine, int resolution, uint64_t seed,
                   uint64_t first, uint64_t count, Stream stream = Stream::shots, bool stratified = false);
// The same with the mesh's emitter table already built (callers that shoot repeatedly).
ShotSums run_shots(const PatchMesh& mesh, const EmitterTable& table, ShotEngine& engine, int resolution,
                   uint64_t seed, uint64_t first, uint64_t count, Stream stream = Stream::shots,
                   bool stratified = false);
// What a shot needs besides its sums: the image (3 H^2 samples), its weights and the form
// factors per patch. Callers that shoot every few bundles keep one, so that no shot allocates
// (at 100k patches and H = 512, 10 MB a shot, paid in page faults and zeroing).
struct ShotScratch {
  std::vector<uint32_t> image;
  std::vector<double> weights, form_factors;
};
// The same into `sums` (its direct light resized to the mesh and zeroed first), with `scratch`.
void run_shots(const PatchMesh& mesh, const EmitterTable& table, ShotEngine& engine, int resolution, uint64_t seed,
               uint64_t first, uint64_t count, Stream stream, bool stratified, ShotSums& sums, ShotScratch& scratch);

// Adds one rendered shot's estimates to `direct` (per patch).
void accumulate_shot(const PatchMesh& mesh, const EmitterTable& table, const ShotDraw& draw,
                     const SiradShot& shot, std::span<const uint32_t> image,
                     std::span<const double> weights, std::vector<glm::dvec3>& direct);
// The same with the per-patch form factors in `form_factors` (resized and zeroed here).
void accumulate_shot(const PatchMesh& mesh, const EmitterTable& table, const ShotDraw& draw,
                     const SiradShot& shot, std::span<const uint32_t> image,
                     std::span<const double> weights, std::vector<glm::dvec3>& direct,
                     std::vector<double>& form_factors);

// A hemicube resolution for the mesh: about 4 pixel samples on face 0 for the median patch
// seen face-on from the scene's bounding radius, even, clamped to [32, 512].
int auto_shot_resolution(const PatchMesh& mesh);

}  // namespace sirad
