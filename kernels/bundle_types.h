/* sirad: types shared by the OpenCL bundle kernels (kernels/bundle.cl) and the C++ host.
 * Compiled both as OpenCL C (prepended to bundle.cl at build time) and as C++; the host
 * static_asserts the sizes. Keep every member 4 bytes wide and the structs free of padding.
 */
#ifndef SIRAD_BUNDLE_TYPES_H
#define SIRAD_BUNDLE_TYPES_H

#ifdef __OPENCL_VERSION__
typedef float sirad_f32;
typedef int sirad_i32;
typedef uint sirad_u32;
#else
#include <cstdint>
typedef float sirad_f32;
typedef std::int32_t sirad_i32;
typedef std::uint32_t sirad_u32;
#endif

/* One bundle of parallel lines (DESIGN.md section 1). World points q (relative to the scene's
 * bounding-sphere centre) map to grid coordinates
 *     X = (q.u) * scale + offset_x,   Y = (q.v) * scale + offset_y,   depth = q.w
 * and the lines of the bundle pass through the integer points X, Y in [0, grid). The host
 * computes every member (direction, frame, jittered offset) in double precision from
 * Random123 Philox keyed by (seed, bundle index) and rounds once, so every device and the
 * C++ reference see bit-identical parameters. Each line stands for a cell of area
 * cell_area = (1/scale)^2 in world units. */
typedef struct {
  sirad_f32 u[3];
  sirad_f32 v[3];
  sirad_f32 w[3];
  sirad_f32 scale;
  sirad_f32 offset_x;
  sirad_f32 offset_y;
  sirad_i32 grid;           /* R: lines per side */
  sirad_i32 rows_per_band;  /* rows of the grid one work-item of count/fill owns */
  sirad_i32 bands;          /* ceil(grid / rows_per_band) */
  sirad_u32 capacity;       /* crossings of one row the scratch can hold (set by the engine) */
  sirad_u32 partial_capacity; /* patches reaching one band the scratch can hold (engine) */
  sirad_f32 background[4];  /* radiance gathered by a line that leaves the scene */
  sirad_f32 depth_tie;      /* depths closer than this count as one place (see bundle.cl) */
} SiradBundle;

/* A patch projected onto the grid plane, ready for the coverage test of kernels/bundle.cl.
 * Edge k of the patch (counter-clockwise in (X, Y)) is stored by a point (ex, ey) on it,
 * its canonical first endpoint, and coefficients such that
 *     e_k(X, Y) = eb[k] * (Y - ey[k]) + ea[k] * (X - ex[k])
 * is > 0 inside. The point and |ea|, |eb| depend only on the edge's two endpoints, taken in
 * lexicographic order, so a neighbour sharing the edge computes exactly -e_k: every line
 * through the shared edge goes to exactly one of the two (bit k of `flags` says whether this
 * patch owns the points with e_k == 0). slope[k] gives the X where edge k meets row Y,
 * ex + slope (Y - ey), for narrowing the rows' spans (unused when ea[k] == 0).
 * depth(X, Y) = z0 + dzdx (X - x0) + dzdy (Y - y0), (x0, y0) its first vertex. rows: the grid rows it may cover,
 * rows = (INT_MAX, -INT_MAX) for a patch that covers no line. Bit 3 of flags: the normal has a
 * positive component along +w (front_pos). */
typedef struct {
  sirad_f32 ex[3];
  sirad_f32 ey[3];
  sirad_f32 ea[3];
  sirad_f32 eb[3];
  sirad_f32 slope[3];
  sirad_f32 x0;
  sirad_f32 y0;
  sirad_f32 z0;
  sirad_f32 dzdx;
  sirad_f32 dzdy;
  sirad_f32 xmin;
  sirad_f32 xmax;
  sirad_i32 rows[2];
  sirad_u32 flags;
  sirad_u32 pad;
} SiradProjected;

#define SIRAD_FRONT_POS 8u


#endif
