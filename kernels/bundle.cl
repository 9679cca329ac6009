/* sirad: one bundle of parallel global lines (DESIGN.md section 1) as OpenCL kernels.
 *
 * The host prepends kernels/bundle_types.h. Per bundle the host enqueues, in order:
 *   project_patches  (one work-item per patch)  patches -> grid plane, CCW order, depth plane
 *   count_crossings  (one work-item per band of grid rows) crossings per line
 *   fill_crossings   (one work-item per band)  prefix sums, crossing lists, sort by depth
 *   gather           (one work-item per patch)  each crossing gathers its front neighbour
 * Coverage of a line by a patch is decided by one predicate, `covers`, used by every pass,
 * so count, fill and gather agree bit for bit on which lines a patch crosses: edge functions
 * evaluated with the edge's endpoints in canonical order (so two patches sharing an edge
 * compute exactly opposite values), a tie rule that gives a line through a shared edge to
 * exactly one of the two patches, and no floating-point contraction.
 * Sums do not depend on thread timing: every buffer element has one writer, and each patch
 * sums its crossings in its own raster order. No atomics anywhere.
 */
#pragma OPENCL FP_CONTRACT OFF

/* Edge function of the directed edge a -> b at p: > 0 when p is to its left. */
inline float edge_raw(float ax, float ay, float bx, float by, float px, float py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

/* Edge k's value at (px, py): the edge function of its canonical direction, times the sign
 * that makes it positive inside (folded into ea, eb; negation is exact in IEEE arithmetic). */
inline float edge_value(const SiradProjected* p, int k, float px, float py) {
  return p->eb[k] * (py - p->ey[k]) + p->ea[k] * (px - p->ex[k]);
}

/* Does the line through grid point (px, py) cross patch p? A point exactly on an edge belongs
 * to the one patch of the two sharing it that owns the edge (a fixed half-plane of edge
 * directions; the neighbour sees the opposite direction). */
inline bool covers(const SiradProjected* p, int px, int py) {
  float fx = (float)px, fy = (float)py;
  for (int k = 0; k < 3; ++k) {
    float e = edge_value(p, k, fx, fy);
    if (!(e > 0.0f || (e == 0.0f && (p->flags & (1u << k))))) return false;
  }
  return true;
}

/* The columns of row py that may hold covered lines: the patch's x-extent narrowed by its
 * edges' half-planes, widened by one cell against rounding. */
inline void row_span(const SiradProjected* p, int py, int grid, int* x0, int* x1) {
  float fy = (float)py;
  float lo = p->xmin, hi = p->xmax;
  for (int k = 0; k < 3; ++k) {
    if (p->ea[k] == 0.0f) {
      /* A horizontal edge decides the whole row, as `covers` would for every cell of it. */
      float e = p->eb[k] * (fy - p->ey[k]);
      if (!(e > 0.0f || (e == 0.0f && (p->flags & (1u << k))))) {
        *x0 = 1;
        *x1 = 0;
        return;
      }
      continue;
    }
    float xc = p->ex[k] + p->slope[k] * (fy - p->ey[k]);
    if (p->ea[k] > 0.0f) lo = fmax(lo, xc);
    else hi = fmin(hi, xc);
  }
  lo = fmax(lo - 1.0f, 0.0f);
  hi = fmin(hi + 1.0f, (float)(grid - 1));
  *x0 = (int)ceil(lo);
  *x1 = (int)floor(hi);
}

/* Visits the lines of row y that cross patch p, as `covers` decides: the cells at the ends
 * of the widened span are tested; the interior, at least one cell inside every edge, needs
 * no test. Every pass walks rows through this one macro, so they agree bit for bit. */
#define FOR_EACH_COVERED(p, y, grid, x)                                  \
  int x##_lo, x##_hi;                                                    \
  row_span(p, y, grid, &x##_lo, &x##_hi);                                \
  for (int x = x##_lo; x <= x##_hi; ++x)                                 \
    if ((x - x##_lo >= 2 && x##_hi - x >= 2) || covers(p, x, y))

inline float depth_at(const SiradProjected* p, int px, int py) {
  return p->z0 + p->dzdx * ((float)px - p->x0) + p->dzdy * ((float)py - p->y0);
}

/* Depth order along +w; at equal depth a patch facing -w comes first, so two back-to-back
 * faces at one place each look outwards; then by patch index. */
inline bool crossing_before(SiradCrossing a, SiradCrossing b) {
  if (a.depth != b.depth) return a.depth < b.depth;
  if ((a.key & 1u) != (b.key & 1u)) return (a.key & 1u) < (b.key & 1u);
  return a.key < b.key;
}

/* Project every patch onto the grid plane of this bundle. `vertices` are relative to the
 * scene's bounding-sphere centre. rows[j] repeats the patch's row range compactly for the
 * band passes, which scan it for every band. */
__kernel void project_patches(__global const float4* vertices, __global const uint4* patches,
                              uint patch_count, __constant SiradBundle* b,
                              __global SiradProjected* projected, __global int2* rows) {
  uint j = get_global_id(0);
  if (j >= patch_count) return;
  uint4 idx = patches[j];
  uint ids[3] = {idx.x, idx.y, idx.z};
  float X[3], Y[3], Z[3];
  for (int k = 0; k < 3; ++k) {
    float4 q = vertices[ids[k]];
    X[k] = (q.x * b->u[0] + q.y * b->u[1] + q.z * b->u[2]) * b->scale + b->offset_x;
    Y[k] = (q.x * b->v[0] + q.y * b->v[1] + q.z * b->v[2]) * b->scale + b->offset_y;
    Z[k] = q.x * b->w[0] + q.y * b->w[1] + q.z * b->w[2];
  }
  SiradProjected p;
  float area2 = edge_raw(X[0], Y[0], X[1], Y[1], X[2], Y[2]);
  /* Counter-clockwise in (X, Y) means the normal has a positive component along +w. */
  bool front_pos = area2 > 0.0f;
  int o[3] = {0, front_pos ? 1 : 2, front_pos ? 2 : 1};
  float vx[3] = {X[o[0]], X[o[1]], X[o[2]]};
  float vy[3] = {Y[o[0]], Y[o[1]], Y[o[2]]};
  float vz[3] = {Z[o[0]], Z[o[1]], Z[o[2]]};
  p.flags = front_pos ? SIRAD_FRONT_POS : 0u;
  for (int k = 0; k < 3; ++k) {
    int k1 = k == 2 ? 0 : k + 1;
    float ax = vx[k], ay = vy[k], bx = vx[k1], by = vy[k1];
    bool swap = bx < ax || (bx == ax && by < ay);
    float px = swap ? bx : ax, py = swap ? by : ay;
    float dxc = (swap ? ax : bx) - px, dyc = (swap ? ay : by) - py;
    float sign = swap ? -1.0f : 1.0f;
    p.ex[k] = px;
    p.ey[k] = py;
    p.eb[k] = sign * dxc;
    p.ea[k] = -(sign * dyc);
    p.slope[k] = p.ea[k] != 0.0f ? -p.eb[k] / p.ea[k] : 0.0f;
    float dx = bx - ax, dy = by - ay;
    if (dy < 0.0f || (dy == 0.0f && dx > 0.0f)) p.flags |= 1u << k;
  }
  p.x0 = vx[0];
  p.y0 = vy[0];
  p.xmin = fmin(vx[0], fmin(vx[1], vx[2]));
  p.xmax = fmax(vx[0], fmax(vx[1], vx[2]));
  p.pad = 0u;
  float a = fabs(area2);
  if (!(a > 0.0f)) {
    /* Seen edge-on: crosses no line. */
    p.z0 = 0.0f; p.dzdx = 0.0f; p.dzdy = 0.0f;
    p.rows[0] = 1; p.rows[1] = 0;
  } else {
    p.z0 = vz[0];
    p.dzdx = ((vz[1] - vz[0]) * (vy[2] - vy[0]) - (vz[2] - vz[0]) * (vy[1] - vy[0])) / a;
    p.dzdy = ((vz[2] - vz[0]) * (vx[1] - vx[0]) - (vz[1] - vz[0]) * (vx[2] - vx[0])) / a;
    float ylo = fmin(vy[0], fmin(vy[1], vy[2]));
    float yhi = fmax(vy[0], fmax(vy[1], vy[2]));
    p.rows[0] = (int)ceil(fmax(ylo, 0.0f));
    p.rows[1] = (int)floor(fmin(yhi, (float)(b->grid - 1)));
  }
  projected[j] = p;
  rows[j] = (int2)(p.rows[0], p.rows[1]);
}

/* Count the crossings of every line in this work-item's band of rows. */
__kernel void count_crossings(__global const SiradProjected* projected,
                              __global const int2* rows, uint patch_count,
                              __constant SiradBundle* b, __global uint* cell_count,
                              __global uint* band_total) {
  int band = get_global_id(0);
  if (band >= b->bands) return;
  int grid = b->grid;
  int r0 = band * b->rows_per_band, r1 = min(r0 + b->rows_per_band, grid);
  for (int c = r0 * grid; c < r1 * grid; ++c) cell_count[c] = 0;
  uint total = 0;
  for (uint j = 0; j < patch_count; ++j) {
    int2 r = rows[j];
    if (r.y < r0 || r.x >= r1) continue;
    SiradProjected p = projected[j];
    int ya = max(r.x, r0), yb = min(r.y, r1 - 1);
    for (int y = ya; y <= yb; ++y) {
      FOR_EACH_COVERED(&p, y, grid, x) {
        cell_count[y * grid + x] += 1;
        total += 1;
      }
    }
  }
  band_total[band] = total;
}

/* Lay out the crossing lists (an exclusive prefix sum over all lines, row-major), fill them
 * in patch order and sort each by depth. status[0] = 1 if they do not fit; status[1] =
 * total crossings of the bundle. */
__kernel void fill_crossings(__global const SiradProjected* projected,
                             __global const int2* rows, uint patch_count,
                             __constant SiradBundle* b, __global uint* cell_count,
                             __global const uint* band_total, __global uint* cell_start,
                             __global SiradCrossing* crossings, __global uint* status) {
  int band = get_global_id(0);
  if (band >= b->bands) return;
  int grid = b->grid;
  uint base = 0, all = 0;
  for (int k = 0; k < b->bands; ++k) {
    if (k < band) base += band_total[k];
    all += band_total[k];
  }
  if (band == 0) {
    status[0] = all > b->capacity ? 1u : 0u;
    status[1] = all;
  }
  if (all > b->capacity) return;
  int r0 = band * b->rows_per_band, r1 = min(r0 + b->rows_per_band, grid);
  /* Starts of this band's lists; the counts become fill cursors. */
  uint running = base;
  for (int c = r0 * grid; c < r1 * grid; ++c) {
    cell_start[c] = running;
    running += cell_count[c];
    cell_count[c] = 0;
  }
  if (r1 == grid) cell_start[grid * grid] = running;
  for (uint j = 0; j < patch_count; ++j) {
    int2 r = rows[j];
    if (r.y < r0 || r.x >= r1) continue;
    SiradProjected p = projected[j];
    uint key = (j << 1) | ((p.flags & SIRAD_FRONT_POS) ? 1u : 0u);
    int ya = max(r.x, r0), yb = min(r.y, r1 - 1);
    for (int y = ya; y <= yb; ++y) {
      FOR_EACH_COVERED(&p, y, grid, x) {
        int c = y * grid + x;
        SiradCrossing s;
        s.depth = depth_at(&p, x, y);
        s.key = key;
        crossings[cell_start[c] + cell_count[c]] = s;
        cell_count[c] += 1;
      }
    }
  }
  /* Sort every list by depth: insertion sort (lists are short), shell gaps for long ones. */
  const int gaps[6] = {57, 23, 10, 4, 1, 0};
  for (int c = r0 * grid; c < r1 * grid; ++c) {
    uint s = cell_start[c], n = cell_count[c];
    if (n < 2) continue;
    for (int g = (n > 64 ? 0 : 4); gaps[g] > 0; ++g) {
      uint gap = (uint)gaps[g];
      for (uint i = gap; i < n; ++i) {
        SiradCrossing t = crossings[s + i];
        uint k = i;
        while (k >= gap && crossing_before(t, crossings[s + k - gap])) {
          crossings[s + k] = crossings[s + k - gap];
          k -= gap;
        }
        crossings[s + k] = t;
      }
    }
  }
}

/* Every crossing of patch j gathers the radiance of its front neighbour on that line, if the
 * neighbour shows j its front face, else the background. gathered[j] = the sum (rgb),
 * hits[j] = the number of lines crossing j. Work-item i takes patches
 * [i * per_item, (i + 1) * per_item): whole runs of patches on a CPU, one on a GPU. */
__kernel void gather(__global const SiradProjected* projected, uint patch_count, uint per_item,
                     __constant SiradBundle* b, __global const uint* cell_start,
                     __global const SiradCrossing* crossings, __global const uint* status,
                     __global const float4* radiance, __global float4* gathered,
                     __global uint* hits) {
  if (status[0] != 0u) return;
  uint first = get_global_id(0) * per_item;
  uint last = min(first + per_item, patch_count);
  int grid = b->grid;
  float4 background = (float4)(b->background[0], b->background[1], b->background[2], 0.0f);
  for (uint j = first; j < last; ++j) {
    SiradProjected p = projected[j];
    uint front_pos = (p.flags & SIRAD_FRONT_POS) ? 1u : 0u;
    uint key = (j << 1) | front_pos;
    float4 sum = (float4)(0.0f);
    uint n = 0;
    for (int y = p.rows[0]; y <= p.rows[1]; ++y) {
      FOR_EACH_COVERED(&p, y, grid, x) {
        int c = y * grid + x;
        uint s = cell_start[c], e = cell_start[c + 1];
        uint k = s;
        while (k < e && crossings[k].key != key) ++k;
        if (k == e) continue; /* cannot happen: fill used the same predicate */
        ++n;
        /* The front neighbour: the next crossing towards the side the normal points to. */
        float4 seen = background;
        if (front_pos) {
          if (k + 1 < e && (crossings[k + 1].key & 1u) == 0u) seen = radiance[crossings[k + 1].key >> 1];
        } else {
          if (k > s && (crossings[k - 1].key & 1u) == 1u) seen = radiance[crossings[k - 1].key >> 1];
        }
        sum += seen;
      }
    }
    gathered[j] = sum;
    hits[j] = n;
  }
}
