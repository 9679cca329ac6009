// sirad: a lightmap baked from a radiosity solution (issue 38): every texel of an atlas
// (scene/atlas.h) lit by the final gather, as a pixel of `sirad image` is, at points on its own
// surface.
//   - A texel's samples are stratified over its square on its chart's plane; each lands on the
//     chart's triangle that holds it, and takes that face's normal and material. A sample on no
//     triangle of the chart (the texel straddles the chart's outline) is left out, and so is one
//     inside a solid: the first face along its normal is met from behind (a floor under a wall
//     that stands on it), and one under a face of another object laid on it at zero gap (a rug:
//     FinalGather::covered). So no sample lies where light cannot be, and a texel's value is the
//     light of its own surface only.
//   - Each kept sample is one estimate of FinalGather::leaving (emission, an emitter sample with
//     its shadow ray, a gather ray); the texel is their mean, in radiance, in the passes' split.
//   - The indirect light, where it can be, comes from a cache of the chart instead of the
//     samples' own gather rays: records at texel corners 4 (else 2) texels apart, each 256 gather
//     rays (FinalGather::arriving), blended bilinearly where a block's four corners lie on the
//     chart outside any solid, see each other and differ by at most 1.25 times (each taken two
//     standard errors towards the others), and a block of 4 lies well within the distance its
//     rays went (the image cache's criteria; bake.cpp). One gather ray a sample leaves the
//     indirect light speckled (a ray that meets a bright patch by a lamp); the cache leaves it
//     smooth, and the direct light's noise (an emitter sample a sample) is what is left.
//   - Its error: the samples are taken as two interleaved halves, each its own estimate a and b
//     (n_a and n_b samples, independent streams); the texel is their weighted mean, and
//     |a - b| sqrt(n_a n_b) / n is an estimate of its standard error (E (a - b)^2 = s^2 n /
//     (n_a n_b) for samples of variance s^2, and the mean's variance is s^2 / n): unbiased in
//     its square, noisy per texel (one degree of freedom), right over many. With the cache, the
//     halves' direct light, and the cache's own in quadrature: the records' errors (the same
//     halves over their rays) blended with the squares of the bilinear weights.
//   - Texels none of whose samples was kept take the mean of their kept neighbours in the same
//     chart, ring by ring, out to the chart's gutter (dilation): filtering at a chart's edge then
//     never reaches the background or another chart.
//   - Seams (Atlas::seams: where two faces are one surface but have different texels): the
//     bilinear lookups of the two sides agree along each, at points half a texel apart, by
//     least changes to the texels within a lookup's reach (projections, bake.cpp): filtering
//     shows no step where a surface crosses from one chart to another (`seams` false: as
//     baked).
// A texel's value depends only on the seed, the atlas and the texel: any split over threads
// gives the same lightmap.
#pragma once
#include <cstdint>
#include <vector>

#include "render/gather.h"
#include "render/image.h"
#include "scene/atlas.h"
#include "scene/scene.h"

namespace sirad {

struct Lightmap {
  Image direct, indirect, combined;  // the atlas's size, rows top first, radiance
  Image error;  // per texel and channel, the estimate of combined's standard error (above)
  // Per texel, the share of its samples that were kept (0: filled by dilation, or empty).
  std::vector<float> coverage;
  uint64_t rays = 0;
  uint64_t cached = 0;  // texels whose indirect light came from their chart's cache
};

// The lightmap of `atlas` (made from `scene`, whose faces `gather`'s mesh was meshed from) at
// `samples` samples per texel (1..4096), each with `lights` emitter samples (1..64:
// FinalGather::leaving). Throws sirad::Error for counts out of range or an atlas not of this
// scene.
Lightmap bake_lightmap(const Scene& scene, const Atlas& atlas, const FinalGather& gather, int samples, int lights = 1,
                       bool seams = true);

}  // namespace sirad
