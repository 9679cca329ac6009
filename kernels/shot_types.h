/* sirad: the view of one first-shot sample (kernels/shot.cl) shared with the C++ host.
 * Compiled both as OpenCL C (after bundle_types.h) and as C++; the host static_asserts the
 * size. Every member is 4 bytes wide; no padding.
 *
 * A shot looks from a point `eye` on an emitter over the hemisphere of the emitter's normal n
 * through a hemicube: face 0 looks along n, faces 1..4 along the four tangent directions
 * (only their upper halves, towards n, are rendered). Face f has a right-handed frame
 * (a, b, c) = axes[9 f .. 9 f + 8], c the direction it looks in. A point q (relative to the
 * scene's bounding-sphere centre) at face coordinates (x, y, z) = ((q - eye).a, .b, .c), z > 0,
 * maps to pixel coordinates
 *     X = (x / z) * scale + offset_x,   Y = (y / z) * scale + offset_y
 * and the pixel samples of the face are the integer points X, Y in [0, resolution): the
 * host jitters the lattice (offset = resolution / 2 - jitter) so that, over shots, every
 * point of the face is sampled with the same density (the estimate of each pixel's form
 * factor is then unbiased). Face 0 renders rows [0, resolution), faces 1..4 rows
 * [resolution / 2, resolution), where y > 0 (b = n for those faces).
 */
#ifndef SIRAD_SHOT_TYPES_H
#define SIRAD_SHOT_TYPES_H

typedef struct {
  sirad_f32 eye[3];
  sirad_f32 axes[45];        /* 5 faces x (a, b, c) */
  sirad_f32 scale;           /* resolution / 2 */
  sirad_f32 offset_x;
  sirad_f32 offset_y;
  sirad_i32 resolution;      /* H, even */
  sirad_i32 rows_per_band;   /* set by the engine */
  sirad_i32 bands_top;       /* bands of face 0; faces 1..4 have bands_side each */
  sirad_i32 bands_side;
  sirad_u32 capacity;        /* triangles reaching one band the scratch can hold (engine) */
  sirad_f32 near_z;          /* geometry with z below this (face coordinates) is clipped */
  sirad_f32 depth_tie;       /* relative: 1/z values this close are one place */
} SiradShot;

/* A pixel whose sample sees no patch, or sees one from behind. */
#define SIRAD_NO_PATCH 0xffffffffu

#endif
