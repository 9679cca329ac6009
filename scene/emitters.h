// sirad: the emitters as the direct light samples them. A light source is usually one polygon of
// the input (the Cornell box's ceiling light, a panel of an office) that the mesher cut into
// many patches, or that a solution read back from PLY or glTF holds as many faces. Sampling it
// patch by patch (a patch chosen by area, a point on it) keeps the samples uniform over the
// light, but not its strata: the points of one stratum of the unit square are spread over
// several patches, so a shadow's edge crosses nearly all of them and a penumbra is as noisy as
// with independent points. find_lights rebuilds each light as the triangle or parallelogram its
// patches tile, so that a stratum of the unit square is one compact cell of the light.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/mesh.h"

namespace sirad {

// An emitting triangle (corners 3) or parallelogram (corners 4, p[2] = p[1] + p[3] - p[0]) of
// one material, the union of one or more emitting patches, its corners counter-clockwise seen
// from its front (`normal`).
struct Light {
  std::array<glm::dvec3, 4> p{};
  int corners = 3;
  glm::dvec3 normal{0.0};
  double area = 0.0;
  glm::dvec3 emission{0.0};

  // The area-preserving map of the unit square onto the light: continuous, so the square's
  // strata are compact cells of the light.
  glm::dvec3 at(double s, double t) const;
};

// The lights of `mesh`: its emitting patches grouped into connected sets of one material and one
// plane, each set the triangle or parallelogram its convex hull is if the set's area fills that
// hull (to 1e-4); else each input triangle of the set rebuilt from its patches where they fill
// it; else each patch a light of its own (always right, only noisier). The lights' areas sum to
// the emitting patches' area (to 1e-4), and a point sampled uniformly on them is uniform over
// the emitting patches.
// `light_of`, if given, is set to each patch's light (its index; -1 for a patch that does not
// emit).
std::vector<Light> find_lights(const PatchMesh& mesh, std::vector<int32_t>* light_of = nullptr);

// The emitting input triangles of `mesh`, in their order, each rebuilt from its patches (the
// extreme points of their vertices: regular subdivision keeps the corners) where they fill it,
// else its patches: the lights of the reference solver (solver/reference.h), which integrates
// Lambert's formula over each.
std::vector<Light> input_triangle_lights(const PatchMesh& mesh);

}  // namespace sirad
