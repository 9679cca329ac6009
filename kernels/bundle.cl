/* sirad: one bundle of parallel global lines (DESIGN.md section 1) as OpenCL kernels.
 *
 * The host prepends kernels/bundle_types.h. Per bundle it enqueues:
 *   project_patches  (runs of patches)  patches -> grid plane, CCW order, depth plane
 *   transfer_band    (one work-item per band of grid rows, written CPU-style), in blocks of
 *                    rows (as many as fit a budget of lines), block by block:
 *        1. collect: rasterise every patch that reaches the block, row by row, appending one
 *           crossing (line, depth, patch) per covered line;
 *        2. sort the crossings by line (counting sort) and each line's list by depth;
 *        3. let every crossing gather its front neighbour on its line, summing per patch;
 *        4. write the band partials: per patch reaching the band, its sum and hits.
 *   combine          (runs of patches)  each patch adds its band partials in band order
 *                                       (one walk per band through its partial list).
 * Coverage of a line by a patch is decided by one predicate, `covers`: edge functions
 * evaluated with the edge's endpoints in canonical order (so two patches sharing an edge
 * compute exactly opposite values), a tie rule that gives a line through a shared edge to
 * exactly one of the two patches, and no floating-point contraction.
 * Sums do not depend on thread timing: every buffer element has one writer, a band sums in
 * its own fixed order and patches add band partials in band order. No atomics anywhere.
 */
#pragma OPENCL FP_CONTRACT OFF

/* Helpers are inlined into every pass (PoCL's clang leaves plain `inline` functions as calls;
 * other compilers get plain `inline`). */
#ifdef __clang__
#define SIRAD_INLINE inline __attribute__((always_inline))
#else
#define SIRAD_INLINE inline
#endif

/* Edge function of the directed edge a -> b at p: > 0 when p is to its left. */
SIRAD_INLINE float edge_raw(float ax, float ay, float bx, float by, float px, float py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

/* Edge k's value at (px, py): the edge function of its canonical direction, times the sign
 * that makes it positive inside (folded into ea, eb; negation is exact in IEEE arithmetic). */
SIRAD_INLINE float edge_value(const SiradProjected* p, int k, float px, float py) {
  return p->eb[k] * (py - p->ey[k]) + p->ea[k] * (px - p->ex[k]);
}

/* Does the line through grid point (px, py) cross patch p? A point exactly on an edge belongs
 * to the one patch of the two sharing it that owns the edge (a fixed half-plane of edge
 * directions; the neighbour sees the opposite direction). */
SIRAD_INLINE bool covers(const SiradProjected* p, int px, int py) {
  float fx = (float)px, fy = (float)py;
#pragma unroll
  for (int k = 0; k < 3; ++k) {
    float e = edge_value(p, k, fx, fy);
    if (!(e > 0.0f || (e == 0.0f && (p->flags & (1u << k))))) return false;
  }
  return true;
}

/* Where row py crosses patch p: the patch's x-extent narrowed by its edges' half-planes,
 * [*lo, *hi] in grid units (empty if *lo > *hi). */
SIRAD_INLINE void row_span(const SiradProjected* p, int py, float* lo_out, float* hi_out) {
  float fy = (float)py;
  float lo = p->xmin, hi = p->xmax;
#pragma unroll
  for (int k = 0; k < 3; ++k) {
    if (p->ea[k] == 0.0f) {
      /* A horizontal edge decides the whole row, as `covers` would for every cell of it. */
      float e = p->eb[k] * (fy - p->ey[k]);
      if (!(e > 0.0f || (e == 0.0f && (p->flags & (1u << k))))) {
        lo = 1.0f;
        hi = 0.0f;
        break;
      }
      continue;
    }
    float xc = p->ex[k] + p->slope[k] * (fy - p->ey[k]);
    /* As fmax / fmin (a NaN xc leaves the bound), without their NaN handling. */
    if (p->ea[k] > 0.0f) lo = xc > lo ? xc : lo;
    else hi = xc < hi ? xc : hi;
  }
  *lo_out = lo;
  *hi_out = hi;
}

/* The span's ends are computed to far better than SIRAD_SPAN_EPS cells (grid coordinates are
 * below 8192, so rounding is below 1e-3 cells), and `covers` agrees with the exact geometry
 * to the same precision: a line farther than that inside the span is covered, one farther
 * outside is not. Only the lines within SIRAD_SPAN_EPS of an end need the exact test. */
#define SIRAD_SPAN_EPS (1.0f / 32.0f)

/* (int)ceil(max(v, 0)) and, for the lines up to v, (int)floor(min(v, hi)) or any value
 * below 0 when that is negative, by truncation (the library's ceil and floor are not
 * inlined as single instructions by every compiler). v is not NaN. */
SIRAD_INLINE int first_line(float v) {
  if (!(v > 0.0f)) return 0;
  int t = (int)v;
  return (float)t < v ? t + 1 : t;
}
SIRAD_INLINE int last_line(float v, float hi) {
  v = v < hi ? v : hi;
  return v >= 0.0f ? (int)v : -1;
}

/* Visits the lines of row y that cross patch p, as `covers` decides. Every pass walks rows
 * through this one macro, so they agree bit for bit. */
#define FOR_EACH_COVERED(p, y, grid, x)                                                    \
  float x##_lo, x##_hi;                                                                    \
  row_span(p, y, &x##_lo, &x##_hi);                                                        \
  int x##_first = first_line(x##_lo - SIRAD_SPAN_EPS);                                     \
  int x##_last = last_line(x##_hi + SIRAD_SPAN_EPS, (float)(grid - 1));                    \
  for (int x = x##_first; x <= x##_last; ++x)                                              \
    if (((float)x >= x##_lo + SIRAD_SPAN_EPS && (float)x <= x##_hi - SIRAD_SPAN_EPS) ||   \
        covers(p, x, y))

SIRAD_INLINE float depth_at(const SiradProjected* p, int px, int py) {
  return p->z0 + p->dzdx * ((float)px - p->x0) + p->dzdy * ((float)py - p->y0);
}

/* A crossing's place on its line as one 64-bit key: depth along +w (as an ordered integer;
 * -0 counts as +0), then the front bit and the patch's position in the band list (patch order),
 * which order_coincident uses to order the faces at one place.
 * Integer order equals the float order of depths, so no comparison branches on floats. */
SIRAD_INLINE ulong crossing_key(float depth, uint front_pos, uint q) {
  uint u = as_uint(depth + 0.0f);
  u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
  return ((ulong)u << 32) | ((ulong)front_pos << 31) | (ulong)q;
}
#define KEY_FRONT(k) ((uint)((k) >> 31) & 1u)
#define KEY_SLOT(k) ((uint)(k) & 0x7fffffffu)

SIRAD_INLINE float key_depth(ulong key) {
  uint u = (uint)(key >> 32);
  return as_float((u & 0x80000000u) ? (u & 0x7fffffffu) : ~u);
}

/* Coincident faces (DESIGN.md section 1): crossings within depth_tie of the first of a run are
 * one place, whatever the rounding of their depths. Within it the faces towards -w come first,
 * the later patch first, then the faces towards +w, the later patch last: each face looks
 * outwards from the place (the two sides of a thin wall), and of faces that face the same way
 * the later patch is on top (nearest to what they face: a rug laid on a floor hides the floor
 * under it). The slot is the position in the band list, which is in patch order. */
SIRAD_INLINE uint tie_rank(ulong key) {
  return KEY_FRONT(key) ? (0x80000000u | KEY_SLOT(key)) : (0x7fffffffu - KEY_SLOT(key));
}
SIRAD_INLINE void order_coincident(__global ulong* s, uint n, float tie) {
  for (uint k = 0; k + 1 < n;) {
    float d0 = key_depth(s[k]);
    uint e = k + 1;
    while (e < n && key_depth(s[e]) - d0 <= tie) ++e;
    for (uint i = k + 1; i < e; ++i) {
      ulong t = s[i];
      uint r = tie_rank(t), m = i;
      for (; m > k && tie_rank(s[m - 1]) > r; --m) s[m] = s[m - 1];
      s[m] = t;
    }
    k = e;
  }
}

/* Sorts s[0..n) ascending: compare-exchange networks for the short lists that are the rule,
 * insertion sort (with shell gaps for long lists) otherwise. */
#define SIRAD_CX(a, b) { ulong lo_ = min(a, b); b = max(a, b); a = lo_; }
SIRAD_INLINE void sort_line(__global ulong* s, uint n) {
  if (n == 2) {
    ulong a = s[0], c = s[1];
    SIRAD_CX(a, c)
    s[0] = a; s[1] = c;
  } else if (n == 3) {
    ulong a = s[0], c = s[1], d = s[2];
    SIRAD_CX(a, c) SIRAD_CX(c, d) SIRAD_CX(a, c)
    s[0] = a; s[1] = c; s[2] = d;
  } else if (n == 4) {
    ulong a = s[0], c = s[1], d = s[2], e = s[3];
    SIRAD_CX(a, c) SIRAD_CX(d, e) SIRAD_CX(a, d) SIRAD_CX(c, e) SIRAD_CX(c, d)
    s[0] = a; s[1] = c; s[2] = d; s[3] = e;
  } else if (n > 4) {
    const uint gaps[6] = {57, 23, 10, 4, 1, 0};
    for (int g = (n > 64 ? 0 : 4); gaps[g] > 0; ++g) {
      uint gap = gaps[g];
      for (uint i = gap; i < n; ++i) {
        ulong t = s[i];
        uint k = i;
        for (; k >= gap && t < s[k - gap]; k -= gap) s[k] = s[k - gap];
        s[k] = t;
      }
    }
  }
}

/* Edge k of a projected patch, from CCW vertex (ax, ay) to (bx, by): canonical point and
 * coefficients, its row-crossing slope and whether it owns the points exactly on it. */
SIRAD_INLINE void set_edge(SiradProjected* p, int k, float ax, float ay, float bx, float by) {
  bool swap = bx < ax || (bx == ax && by < ay);
  float px = swap ? bx : ax, py = swap ? by : ay;
  float dxc = (swap ? ax : bx) - px, dyc = (swap ? ay : by) - py;
  float sign = swap ? -1.0f : 1.0f;
  p->ex[k] = px;
  p->ey[k] = py;
  p->eb[k] = sign * dxc;
  p->ea[k] = -(sign * dyc);
  p->slope[k] = p->ea[k] != 0.0f ? -p->eb[k] / p->ea[k] : 0.0f;
  float dx = bx - ax, dy = by - ay;
  if (dy < 0.0f || (dy == 0.0f && dx > 0.0f)) p->flags |= 1u << k;
}

/* Patch j projected onto the grid plane of bundle *b (a private copy: callers hold their
 * bundles in constant or global memory), with its row range. `vertices` are relative to the
 * scene's bounding-sphere centre. */
SIRAD_INLINE void project_one(__global const float4* vertices, __global const uint4* patches, uint j,
                              const SiradBundle* b, SiradProjected* out) {
  uint4 idx = patches[j];
  float4 q0 = vertices[idx.x], q1 = vertices[idx.y], q2 = vertices[idx.z];
#define SIRAD_PROJECT(q, X, Y, Z)                                                   \
  float X = (q.x * b->u[0] + q.y * b->u[1] + q.z * b->u[2]) * b->scale + b->offset_x; \
  float Y = (q.x * b->v[0] + q.y * b->v[1] + q.z * b->v[2]) * b->scale + b->offset_y; \
  float Z = q.x * b->w[0] + q.y * b->w[1] + q.z * b->w[2];
  SIRAD_PROJECT(q0, X0, Y0, Z0)
  SIRAD_PROJECT(q1, X1, Y1, Z1)
  SIRAD_PROJECT(q2, X2, Y2, Z2)
#undef SIRAD_PROJECT
  float area2 = edge_raw(X0, Y0, X1, Y1, X2, Y2);
  /* Counter-clockwise in (X, Y) means the normal has a positive component along +w;
   * otherwise swap the last two vertices. */
  bool front_pos = area2 > 0.0f;
  float x1 = front_pos ? X1 : X2, y1 = front_pos ? Y1 : Y2, z1 = front_pos ? Z1 : Z2;
  float x2 = front_pos ? X2 : X1, y2 = front_pos ? Y2 : Y1, z2 = front_pos ? Z2 : Z1;
  SiradProjected p;
  p.flags = front_pos ? SIRAD_FRONT_POS : 0u;
  set_edge(&p, 0, X0, Y0, x1, y1);
  set_edge(&p, 1, x1, y1, x2, y2);
  set_edge(&p, 2, x2, y2, X0, Y0);
  p.x0 = X0;
  p.y0 = Y0;
  p.xmin = fmin(X0, fmin(x1, x2));
  p.xmax = fmax(X0, fmax(x1, x2));
  p.pad = 0u;
  float a = fabs(area2);
  if (!(a > 0.0f)) {
    /* Seen edge-on: crosses no line. */
    p.z0 = 0.0f;
    p.dzdx = 0.0f;
    p.dzdy = 0.0f;
    p.rows[0] = 0x7fffffff; /* an empty range that no band's filter lets through */
    p.rows[1] = -0x7fffffff;
  } else {
    p.z0 = Z0;
    p.dzdx = ((z1 - Z0) * (y2 - Y0) - (z2 - Z0) * (y1 - Y0)) / a;
    p.dzdy = ((z2 - Z0) * (x1 - X0) - (z1 - Z0) * (x2 - X0)) / a;
    float ylo = fmin(Y0, fmin(y1, y2));
    float yhi = fmax(Y0, fmax(y1, y2));
    p.rows[0] = (int)ceil(fmax(ylo, 0.0f));
    p.rows[1] = (int)floor(fmin(yhi, (float)(b->grid - 1)));
  }
  *out = p;
}

/* Project every patch onto the grid plane of this bundle. rows[j] repeats the patch's row
 * range compactly for the band pass, which scans it once per band. Work-item i takes patches
 * [i * per_item, (i + 1) * per_item). */
__kernel void project_patches(__global const float4* vertices, __global const uint4* patches,
                              uint patch_count, uint per_item, __constant SiradBundle* b,
                              __global SiradProjected* projected, __global int2* rows) {
  uint last = min((uint)get_global_id(0) * per_item + per_item, patch_count);
  const SiradBundle bundle = *b;
  for (uint j = get_global_id(0) * per_item; j < last; ++j) {
    SiradProjected p;
    project_one(vertices, patches, j, &bundle, &p);
    projected[j] = p;
    rows[j] = (int2)(p.rows[0], p.rows[1]);
  }
}

/* project_patches for CPUs, eight patches at a time in float8 lanes (explicit SIMD: PoCL does
 * not vectorise across work-items here). Lane for lane the same operations in the same
 * order as project_patches, so the same bits. Work-item i takes patches
 * [i * per_item, (i + 1) * per_item). */
SIRAD_INLINE void set_edge8(float8 ax, float8 ay, float8 bx, float8 by, float* ex, float* ey,
                            float* ea, float* eb, float* slope, int8* flags, int k) {
  int8 swap = (bx < ax) | ((bx == ax) & (by < ay));
  float8 px = select(ax, bx, swap), py = select(ay, by, swap);
  float8 dxc = select(bx, ax, swap) - px, dyc = select(by, ay, swap) - py;
  float8 sign = select((float8)(1.0f), (float8)(-1.0f), swap);
  float8 b_ = sign * dxc;
  float8 a_ = -(sign * dyc);
  vstore8(px, 0, ex);
  vstore8(py, 0, ey);
  vstore8(b_, 0, eb);
  vstore8(a_, 0, ea);
  vstore8(select((float8)(0.0f), -b_ / a_, a_ != 0.0f), 0, slope);
  float8 dx = bx - ax, dy = by - ay;
  int8 own = (dy < 0.0f) | ((dy == 0.0f) & (dx > 0.0f));
  *flags |= own & (int8)(1 << k);
}

__kernel void project_patches8(__global const float4* restrict vertices, __global const uint4* restrict patches,
                               uint patch_count, uint per_item, __constant SiradBundle* b,
                               __global SiradProjected* restrict projected, __global int2* restrict rows) {
  uint first = (uint)get_global_id(0) * per_item;
  uint last = min(first + per_item, patch_count);
  for (uint j0 = first; j0 < last; j0 += 8) {
    uint lanes = min(8u, last - j0);
    float q[9][8];
    for (uint l = 0; l < 8; ++l) {
      uint4 idx = patches[j0 + min(l, lanes - 1)];
      float4 v0 = vertices[idx.x], v1 = vertices[idx.y], v2 = vertices[idx.z];
      q[0][l] = v0.x; q[1][l] = v0.y; q[2][l] = v0.z;
      q[3][l] = v1.x; q[4][l] = v1.y; q[5][l] = v1.z;
      q[6][l] = v2.x; q[7][l] = v2.y; q[8][l] = v2.z;
    }
#define SIRAD_PROJECT8(o, X, Y, Z)                                                               \
    float8 X, Y, Z;                                                                              \
    {                                                                                            \
      float8 qx = vload8(0, q[o]), qy = vload8(0, q[o + 1]), qz = vload8(0, q[o + 2]);           \
      X = (qx * b->u[0] + qy * b->u[1] + qz * b->u[2]) * b->scale + b->offset_x;                 \
      Y = (qx * b->v[0] + qy * b->v[1] + qz * b->v[2]) * b->scale + b->offset_y;                 \
      Z = qx * b->w[0] + qy * b->w[1] + qz * b->w[2];                                            \
    }
    SIRAD_PROJECT8(0, X0, Y0, Z0)
    SIRAD_PROJECT8(3, X1, Y1, Z1)
    SIRAD_PROJECT8(6, X2, Y2, Z2)
#undef SIRAD_PROJECT8
    float8 area2 = (X1 - X0) * (Y2 - Y0) - (Y1 - Y0) * (X2 - X0);
    int8 fp = area2 > 0.0f;
    float8 x1 = select(X2, X1, fp), y1 = select(Y2, Y1, fp), z1 = select(Z2, Z1, fp);
    float8 x2 = select(X1, X2, fp), y2 = select(Y1, Y2, fp), z2 = select(Z1, Z2, fp);
    float ex[3][8], ey[3][8], ea[3][8], eb[3][8], sl[3][8];
    int8 flags = fp & (int8)(SIRAD_FRONT_POS);
    set_edge8(X0, Y0, x1, y1, ex[0], ey[0], ea[0], eb[0], sl[0], &flags, 0);
    set_edge8(x1, y1, x2, y2, ex[1], ey[1], ea[1], eb[1], sl[1], &flags, 1);
    set_edge8(x2, y2, X0, Y0, ex[2], ey[2], ea[2], eb[2], sl[2], &flags, 2);
    float8 a = fabs(area2);
    int8 vis = a > 0.0f;
    float8 ylo = fmin(Y0, fmin(y1, y2)), yhi = fmax(Y0, fmax(y1, y2));
    float o[7][8];
    int ri[3][8];
    vstore8(fmin(X0, fmin(x1, x2)), 0, o[0]);
    vstore8(fmax(X0, fmax(x1, x2)), 0, o[1]);
    vstore8(select((float8)(0.0f), Z0, vis), 0, o[2]);
    vstore8(select((float8)(0.0f), ((z1 - Z0) * (y2 - Y0) - (z2 - Z0) * (y1 - Y0)) / a, vis), 0, o[3]);
    vstore8(select((float8)(0.0f), ((z2 - Z0) * (x1 - X0) - (z1 - Z0) * (x2 - X0)) / a, vis), 0, o[4]);
    vstore8(X0, 0, o[5]);
    vstore8(Y0, 0, o[6]);
    vstore8(select((int8)(0x7fffffff), convert_int8(ceil(fmax(ylo, 0.0f))), vis), 0, ri[0]);
    vstore8(select((int8)(-0x7fffffff), convert_int8(floor(fmin(yhi, (float)(b->grid - 1)))), vis), 0, ri[1]);
    vstore8(flags, 0, ri[2]);
    for (uint l = 0; l < lanes; ++l) {
      SiradProjected p;
      for (int k = 0; k < 3; ++k) {
        p.ex[k] = ex[k][l];
        p.ey[k] = ey[k][l];
        p.ea[k] = ea[k][l];
        p.eb[k] = eb[k][l];
        p.slope[k] = sl[k][l];
      }
      p.xmin = o[0][l];
      p.xmax = o[1][l];
      p.z0 = o[2][l];
      p.dzdx = o[3][l];
      p.dzdy = o[4][l];
      p.x0 = o[5][l];
      p.y0 = o[6][l];
      p.rows[0] = ri[0][l];
      p.rows[1] = ri[1][l];
      p.flags = (uint)ri[2][l];
      p.pad = 0u;
      projected[j0 + l] = p;
      rows[j0 + l] = (int2)(p.rows[0], p.rows[1]);
    }
  }
}

/* One band of grid rows, in blocks of rows_per_block rows (see the banner). Scratch per band:
 *   band_list, band_radiance, acc, acc_hits, out_patch: b->partial_capacity entries (the
 *     patches that reach the band, in patch order; their radiance; their sums; compacted at
 *     the end into the band partials; out_patch first holds the visiting order below);
 *   e_x, e_sort, s_sort: b->capacity crossings of one block: line (within the block, row
 *     major) and crossing_key as collected, and the keys sorted by line; line_count:
 *     rows_per_block * grid counters (zero between blocks).
 * band_stats[4 band + 0..3] = the most crossings in one block, partials written, patches that
 * reach the band, crossings in the band; the first and third are reported even when they do
 * not fit, so the host can grow the scratch and run the bundle again.
 * Each patch's sum adds its lines in row-major order whatever the block height: a patch
 * crosses a line at most once and lines are gathered in order.
 * A block visits only the slots that reach it: the slots sorted by the first block they reach
 * (a counting sort into out_patch), those still reaching it from earlier blocks kept compacted
 * at the front of that order. A band costs the sum of its patches' blocks, not patches times
 * blocks (blocks per band grow with the grid: 54 at a million patches on a CPU). The order of
 * collection does not matter: each line's crossings are sorted by their whole key, slot
 * included. */
__kernel void transfer_band(__global const SiradProjected* restrict projected,
                            __global const int2* restrict rows, uint patch_count, int rows_per_block,
                            __constant SiradBundle* b, __global const float4* restrict radiance,
                            __global uint* restrict band_list, __global uint* restrict e_x,
                            __global ulong* restrict e_sort, __global ulong* restrict s_sort,
                            __global uint* restrict line_count, __global uint* restrict out_patch,
                            __global float4* restrict acc, __global uint* restrict acc_hits,
                            __global float4* restrict band_radiance, __global uint* restrict band_stats) {
  int band = get_global_id(0);
  if (band >= b->bands) return;
  const int grid = b->grid;
  const uint cap = b->capacity, lcap = b->partial_capacity;
  const int r0 = band * b->rows_per_band, r1 = min(r0 + b->rows_per_band, grid);
  band_list += (size_t)band * lcap;
  out_patch += (size_t)band * lcap;
  acc += (size_t)band * lcap;
  acc_hits += (size_t)band * lcap;
  band_radiance += (size_t)band * lcap;
  e_x += (size_t)band * cap;
  e_sort += (size_t)band * cap;
  s_sort += (size_t)band * cap;
  __global uint* count = line_count + (size_t)band * rows_per_block * grid;
  __global uint* stats = band_stats + 4 * band;

  /* 1. The patches that reach the band, in patch order. */
  uint patches = 0;
  for (uint j = 0; j < patch_count; ++j) {
    int2 r = rows[j];
    if (r.y < r0 || r.x >= r1) continue;
    if (patches < lcap) band_list[patches] = j;
    ++patches;
  }
  stats[0] = 0;
  stats[1] = 0;
  stats[2] = patches;
  stats[3] = 0;
  if (patches > lcap) return;
  for (uint q = 0; q < patches; ++q) {
    acc[q] = (float4)(0.0f);
    acc_hits[q] = 0;
    band_radiance[q] = radiance[band_list[q]];
  }
  /* The visiting order: slots by first block (count[] as the histogram; blocks <= grid). */
  __global uint* order = out_patch;
  const int blocks = (r1 - r0 + rows_per_block - 1) / rows_per_block;
  for (int k = 0; k < blocks; ++k) count[k] = 0;
  for (uint q = 0; q < patches; ++q) count[(max(rows[band_list[q]].x, r0) - r0) / rows_per_block] += 1;
  uint placed = 0;
  for (int k = 0; k < blocks; ++k) {
    uint c = count[k];
    count[k] = placed;
    placed += c;
  }
  for (uint q = 0; q < patches; ++q) order[count[(max(rows[band_list[q]].x, r0) - r0) / rows_per_block]++] = q;
  for (int i = 0; i < rows_per_block * grid; ++i) count[i] = 0;

  const float4 background = (float4)(b->background[0], b->background[1], b->background[2], 0.0f);
  uint block_max = 0, total = 0;
  uint active = 0, next = 0; /* order[0, active): slots reaching this block from earlier ones */
  for (int y0 = r0; y0 < r1; y0 += rows_per_block) {
    const int y1 = min(y0 + rows_per_block, r1);
    /* The slots whose first block this is: order[next, started). */
    uint started = next;
    while (started < patches && max(rows[band_list[order[started]]].x, r0) < y1) ++started;
    /* 2. Collect the block's crossings (line within the block; key: position in the band
     * list, front bit), patch by patch and row by row, counting per line, and the range of
     * lines touched. Slots that reach the next block stay at the front of the order (written
     * at or before the entry being read). */
    uint m = 0, kept = 0;
    int la = rows_per_block * grid, lb = -1;
    for (uint i = 0; i < active + (started - next); ++i) {
      uint q = order[i < active ? i : next + (i - active)];
      uint j = band_list[q];
      int2 r = rows[j];
      if (r.y >= y1) order[kept++] = q;
      SiradProjected p = projected[j];
      uint front_pos = (p.flags & SIRAD_FRONT_POS) ? 1u : 0u;
      const int ya = max(r.x, y0), yb = min(r.y, y1 - 1);
      for (int y = ya; y <= yb; ++y) {
        const int base = (y - y0) * grid;
        FOR_EACH_COVERED(&p, y, grid, x) {
          if (m < cap) {
            e_x[m] = (uint)(base + x);
            e_sort[m] = crossing_key(depth_at(&p, x, y), front_pos, q);
            count[base + x] += 1;
            la = min(la, base + x);
            lb = max(lb, base + x);
          }
          ++m;
        }
      }
    }
    active = kept;
    next = started;
    total += m;
    block_max = max(block_max, m);
    if (m > cap) {
      for (int l = la; l <= lb; ++l) count[l] = 0;
      continue; /* keep counting: the host needs the largest block */
    }

    /* 3. Counting sort by line; afterwards count[l] ends line l's list. */
    uint running = 0;
    for (int l = la; l <= lb; ++l) {
      uint c = count[l];
      count[l] = running;
      running += c;
    }
    for (uint i = 0; i < m; ++i) {
      uint at = count[e_x[i]]++;
      s_sort[at] = e_sort[i];
    }

    /* 4. Each line: sort by depth; every crossing gathers its front neighbour (the next
     * crossing towards the side its normal points to, if that one faces back; else the
     * background). */
    uint start = 0;
    for (int l = la; l <= lb; ++l) {
      uint end = count[l], n = end - start;
      count[l] = 0;
      if (n == 0) continue;
      sort_line(s_sort + start, n);
      order_coincident(s_sort + start, n, b->depth_tie);
      for (uint k = start; k < end; ++k) {
        ulong key = s_sort[k];
        float4 seen = background;
        if (KEY_FRONT(key)) {
          if (k + 1 < end && KEY_FRONT(s_sort[k + 1]) == 0u) seen = band_radiance[KEY_SLOT(s_sort[k + 1])];
        } else if (k > start && KEY_FRONT(s_sort[k - 1])) {
          seen = band_radiance[KEY_SLOT(s_sort[k - 1])];
        }
        acc[KEY_SLOT(key)] += seen;
        acc_hits[KEY_SLOT(key)] += 1;
      }
      start = end;
    }
  }
  stats[0] = block_max;
  stats[3] = total;
  if (block_max > cap) return;

  /* 5. Band partials: the patches with crossings here, in patch order. */
  uint partials = 0;
  for (uint q = 0; q < patches; ++q) {
    if (acc_hits[q] == 0) continue;
    out_patch[partials] = band_list[q];
    acc[partials] = acc[q];
    acc_hits[partials] = acc_hits[q];
    ++partials;
  }
  stats[1] = partials;
}

/* Each patch adds its band partials, in band order. gathered[j] = sum over the lines crossing
 * j of what they bring (rgb), hits[j] = the number of those lines. Work-item i takes patches
 * [i * per_item, (i + 1) * per_item): it zeroes them, then walks the partial list (in patch
 * order) of each band its patches reach, from its first entry in the range (one binary search
 * per band) to the range's end, adding as it goes: every patch's sum is 0 + its partials in
 * band order.
 * Nothing is written when a band overflowed. */
__kernel void combine(__global const int2* restrict rows, uint patch_count, uint per_item,
                      __constant SiradBundle* b,
                      __global const uint* restrict partial_patch,
                      __global const float4* restrict partial_sum, __global const uint* restrict partial_hits,
                      __global const uint* restrict band_stats, __global float4* restrict gathered,
                      __global uint* restrict hits) {
  for (int k = 0; k < b->bands; ++k)
    if (band_stats[4 * k] > b->capacity || band_stats[4 * k + 2] > b->partial_capacity) return;
  uint first = get_global_id(0) * per_item;
  uint last = min(first + per_item, patch_count);
  if (first >= last) return;
  int ylo = 0x7fffffff, yhi = -1;
  for (uint j = first; j < last; ++j) {
    gathered[j] = (float4)(0.0f);
    hits[j] = 0;
    int2 r = rows[j];
    if (r.x <= r.y) {
      ylo = min(ylo, r.x);
      yhi = max(yhi, r.y);
    }
  }
  if (yhi < 0) return;
  for (int band = ylo / b->rows_per_band; band <= yhi / b->rows_per_band; ++band) {
    uint base = (uint)band * b->partial_capacity;
    uint count = band_stats[4 * band + 1];
    __global const uint* pp = partial_patch + base;
    if (count == 0 || pp[count - 1] < first || pp[0] >= last) continue;
    uint lo = 0, hi = count;
    while (lo < hi) {
      uint mid = (lo + hi) / 2;
      if (pp[mid] < first) lo = mid + 1;
      else hi = mid;
    }
    for (uint k = lo; k < count; ++k) {
      uint j = pp[k];
      if (j >= last) break;
      gathered[j] += partial_sum[base + k];
      hits[j] += partial_hits[base + k];
    }
  }
}
