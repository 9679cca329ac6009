// sirad: which faces light can reach, decided at load time by random walks from them (DESIGN.md
// section 1, "Two-sided surfaces" and "Faces no light reaches").
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "scene/mesh.h"
#include "scene/rays.h"

namespace sirad {

// For each patch first .. first + count - 1 of `mesh` (meshed one patch per input triangle, so a
// patch is a face), whether light can reach its front: one of up to kMaxWalks cosine random walks
// from points on it (kWalkBounces bounces each, over fronts only; a back or nothing ends a walk)
// meets an emitter's front, or from a point of it sees a point of one (shadow rays from its
// start to a point of every emitting face, kLightsTried at most, and from each bounce to one
// picked at random: a face in sight of a small lamp or of a sliver of a sky is found by its first
// walks). An emitting face counts where it lights some front (the first hit of a walk).
// Walks from a point under a later face at its place (rays.covered) count for nothing.
// `budget`: the walks of all `count` faces together (each gets at least kMinWalks).
std::vector<uint8_t> light_reaches(const PatchMesh& mesh, const RayScene& rays, std::size_t first, std::size_t count,
                                   std::size_t budget);

inline constexpr std::size_t kWalkBudget = std::size_t{1} << 18;
inline constexpr int kMinWalks = 8, kMaxWalks = 64, kWalkBounces = 8;
inline constexpr std::size_t kLightsTried = 64;  // shadow rays from a walk's start, at most
inline constexpr std::size_t kMaxMarkedFaces = std::size_t{1} << 18;  // scene.h mark_unlit_faces looks at no more

}  // namespace sirad
