/* sirad: bundles of parallel global lines for devices with many lanes (GPUs), a batch of them
 * per launch: the "wide" transfer path. The host prepends kernels/bundle_types.h and kernels/bundle.cl (whose
 * helpers, `covers`, FOR_EACH_COVERED, crossing_key and the coincident-face order, decide
 * every crossing here exactly as on the band path and in the C++ reference).
 *
 * No work-item scans the mesh: every pass is one work-item per patch, per span (one patch's
 * crossings of one grid row) or per line, and each does work proportional to its own item.
 * Per batch of bundles (see "The passes") the host enqueues:
 *   wide_project          (per patch)  patches -> grid plane (kernels/bundle.cl project_one)
 *   wide_count_spans      (per patch)  rows each patch reaches            -> span_start
 *   scan                               span_start becomes each patch's first span
 *   wide_count_crossings  (per span)   lines the span covers              -> cross_start;
 *                                      per line, crossings on it          -> line_count
 *   scan, scan                         cross_start: each span's first crossing (so crossings
 *                                      are numbered patch by patch, row by row, x by x: the
 *                                      "emit order"); line_start: each line's first slot
 *   wide_emit             (per span)   each crossing's key (depth, front, patch) and emit
 *                                      number into its line's slots (line_count back to 0)
 *   wide_gather_lines     (per line)   sort the line by key, order coincident faces, and write
 *                                      what each crossing sees at its emit number
 *   wide_sum_patches      (per patch)  add its crossings in emit order: row-major line order,
 *                                      the order the C++ reference adds them, so the same bits
 * Sums do not depend on thread timing: integer atomics only count and place crossings in a
 * line's slots, and every line is then sorted by its keys, which are unique (a patch crosses a
 * line at most once); every float is written by one work-item and added in a fixed order.
 * Capacities: spans and crossings are placed only below span_cap and cross_cap; the host reads
 * the batch's totals (span_start[patches], line_start[lines]) and runs the batch again with room
 * when one did not fit.
 */

/* ---- Exclusive scan of n = min(len[len_at], cap) uints, in place or not: out[i] = in[0] +
 * ... + in[i - 1] for i <= n (out[n] the total). `items` work-items each take one chunk:
 * scan_reduce sums the chunks, scan_partials (one work-item) scans the chunk sums, scan_down
 * writes the chunks' prefixes. Integers: the result does not depend on the split. ---- */
SIRAD_INLINE uint scan_length(__global const uint* len, uint len_at, uint cap) {
  uint n = len[len_at];
  return n < cap ? n : cap;
}

__kernel void scan_reduce(__global const uint* restrict in, __global const uint* len, uint len_at, uint cap,
                          __global uint* restrict partial) {
  uint items = get_global_size(0), i = get_global_id(0);
  uint n = scan_length(len, len_at, cap);
  uint chunk = (n + items - 1) / items;
  uint a = min(i * chunk, n), b = min(a + chunk, n);
  uint s = 0;
  for (uint k = a; k < b; ++k) s += in[k];
  partial[i] = s;
}

__kernel void scan_partials(__global uint* partial, uint items) {
  if (get_global_id(0) != 0) return;
  uint running = 0;
  for (uint i = 0; i < items; ++i) {
    uint c = partial[i];
    partial[i] = running;
    running += c;
  }
  partial[items] = running;
}

/* In place (in == out) each work-item reads an entry of its chunk before writing it. */
__kernel void scan_down(__global const uint* in, __global uint* out, __global const uint* len, uint len_at, uint cap,
                        __global const uint* restrict partial) {
  uint items = get_global_size(0), i = get_global_id(0);
  uint n = scan_length(len, len_at, cap);
  uint chunk = (n + items - 1) / items;
  uint a = min(i * chunk, n), b = min(a + chunk, n);
  uint running = partial[i];
  for (uint k = a; k < b; ++k) {
    uint c = in[k];
    out[k] = running;
    running += c;
  }
  if (i == items - 1) out[n] = partial[items];
}

/* ---- The passes ----
 * A launch runs a batch of bundles with the same grid over the same radiance: "patch p" is
 * patch p % n of bundle p / n (n patches a bundle), line l is line l % grid^2 of bundle
 * l / grid^2, and every total and offset counts over the whole batch. */

/* Patch p projected by its bundle (kernels/bundle.cl project_one); rows as project_patches. */
__kernel void wide_project(__global const float4* restrict vertices, __global const uint4* restrict patches, uint n,
                           uint batch, __global const SiradBundle* restrict bundles,
                           __global SiradProjected* restrict projected, __global int2* restrict rows) {
  uint p = get_global_id(0);
  if (p >= n * batch) return;
  const SiradBundle b = bundles[p / n];
  SiradProjected q;
  project_one(vertices, patches, p % n, &b, &q);
  projected[p] = q;
  rows[p] = (int2)(q.rows[0], q.rows[1]);
}

/* span_start[p] = the rows patch p reaches (0 for a patch seen edge-on). */
__kernel void wide_count_spans(__global const int2* restrict rows, uint patches, __global uint* restrict span_start) {
  uint p = get_global_id(0);
  if (p >= patches) return;
  int2 r = rows[p];
  span_start[p] = r.y >= r.x ? (uint)(r.y - r.x + 1) : 0u;
}

/* The patch of span s: the last p with span_start[p] <= s (a patch with no spans shares its
 * start with the next, so the last one is the patch that has s). */
SIRAD_INLINE uint span_patch(__global const uint* span_start, uint patches, uint s) {
  uint lo = 0, hi = patches; /* span_start[lo] <= s < span_start[hi] */
  while (hi - lo > 1) {
    uint mid = lo + (hi - lo) / 2;
    if (span_start[mid] <= s) lo = mid;
    else hi = mid;
  }
  return lo;
}

/* Span s of the batch: its patch *p and its row *y; false for s beyond the spans placed. */
SIRAD_INLINE bool span_at(uint s, __global const uint* span_start, uint patches, uint span_cap, __global const int2* rows,
                          uint* p, int* y) {
  if (s >= min(span_start[patches], span_cap)) return false;
  *p = span_patch(span_start, patches, s);
  *y = rows[*p].x + (int)(s - span_start[*p]);
  return true;
}

/* cross_start[s] = the lines span s covers; each of them counted on its line. */
__kernel void wide_count_crossings(__global const SiradProjected* restrict projected, __global const int2* restrict rows,
                                   uint n, uint batch, __global const SiradBundle* restrict bundles,
                                   __global const uint* restrict span_start, uint span_cap,
                                   __global uint* restrict cross_start, __global uint* line_count) {
  uint s = get_global_id(0), p;
  int y;
  if (!span_at(s, span_start, n * batch, span_cap, rows, &p, &y)) return;
  const int grid = bundles[0].grid;
  SiradProjected q = projected[p];
  __global uint* count = line_count + (size_t)(p / n) * (uint)grid * (uint)grid;
  uint c = 0;
  FOR_EACH_COVERED(&q, y, grid, x) {
    atomic_inc(&count[y * grid + x]);
    ++c;
  }
  cross_start[s] = c;
}

/* Each crossing of span s: its key into a free slot of its line, with its emit number (the
 * span's first crossing plus its place in the span). Slots are taken by counting line_count
 * back down, which leaves it 0 for the next batch. */
__kernel void wide_emit(__global const SiradProjected* restrict projected, __global const int2* restrict rows, uint n,
                        uint batch, __global const SiradBundle* restrict bundles, __global const uint* restrict span_start,
                        uint span_cap, __global const uint* restrict cross_start, __global const uint* restrict line_start,
                        uint cross_cap, __global uint* line_count, __global ulong* restrict keys, __global uint* restrict emit) {
  uint s = get_global_id(0), p;
  int y;
  if (!span_at(s, span_start, n * batch, span_cap, rows, &p, &y)) return;
  const int grid = bundles[0].grid;
  SiradProjected q = projected[p];
  uint front_pos = (q.flags & SIRAD_FRONT_POS) ? 1u : 0u;
  const uint line0 = (p / n) * (uint)grid * (uint)grid; /* the bundle's first line */
  uint e = cross_start[s];
  FOR_EACH_COVERED(&q, y, grid, x) {
    uint l = line0 + (uint)(y * grid + x);
    uint at = line_start[l] + atomic_dec(&line_count[l]) - 1u;
    if (at < cross_cap) {
      keys[at] = crossing_key(depth_at(&q, x, y), front_pos, p % n);
      emit[at] = e;
    }
    ++e;
  }
}

/* Sorts keys[0..n) ascending, carrying vals along (keys are unique). */
SIRAD_INLINE void sort_pairs(__global ulong* keys, __global uint* vals, uint n) {
  const uint gaps[6] = {57, 23, 10, 4, 1, 0};
  for (int g = (n > 64 ? 0 : 4); gaps[g] > 0; ++g) {
    uint gap = gaps[g];
    for (uint i = gap; i < n; ++i) {
      ulong t = keys[i];
      uint v = vals[i];
      uint k = i;
      for (; k >= gap && t < keys[k - gap]; k -= gap) {
        keys[k] = keys[k - gap];
        vals[k] = vals[k - gap];
      }
      keys[k] = t;
      vals[k] = v;
    }
  }
}

/* order_coincident (kernels/bundle.cl) carrying vals along. */
SIRAD_INLINE void order_coincident_pairs(__global ulong* s, __global uint* vals, uint n, float tie) {
  for (uint k = 0; k + 1 < n;) {
    float d0 = key_depth(s[k]);
    uint e = k + 1;
    while (e < n && key_depth(s[e]) - d0 <= tie) ++e;
    for (uint i = k + 1; i < e; ++i) {
      ulong t = s[i];
      uint v = vals[i];
      uint r = tie_rank(t), m = i;
      for (; m > k && tie_rank(s[m - 1]) > r; --m) {
        s[m] = s[m - 1];
        vals[m] = vals[m - 1];
      }
      s[m] = t;
      vals[m] = v;
    }
    k = e;
  }
}

/* Line l: its crossings in depth order, then each takes its front neighbour's radiance (the
 * next crossing towards the side its normal points to, if that one faces back; else the
 * background) into seen[its emit number]. */
__kernel void wide_gather_lines(uint batch, __global const SiradBundle* restrict bundles, __global const uint* restrict line_start,
                                uint cross_cap, __global ulong* restrict keys, __global uint* restrict emit,
                                __global const float4* restrict radiance, __global float4* restrict seen) {
  uint l = get_global_id(0);
  const uint per_bundle = (uint)bundles[0].grid * (uint)bundles[0].grid, lines = per_bundle * batch;
  if (l >= lines || line_start[lines] > cross_cap) return;
  uint start = line_start[l], end = line_start[l + 1], n = end - start;
  if (n == 0) return;
  __global const SiradBundle* b = bundles + l / per_bundle;
  __global ulong* k = keys + start;
  __global uint* v = emit + start;
  if (n > 1) {
    sort_pairs(k, v, n);
    order_coincident_pairs(k, v, n, b->depth_tie);
  }
  const float4 background = (float4)(b->background[0], b->background[1], b->background[2], 0.0f);
  for (uint i = 0; i < n; ++i) {
    ulong key = k[i];
    float4 r = background;
    if (KEY_FRONT(key)) {
      if (i + 1 < n && KEY_FRONT(k[i + 1]) == 0u) r = radiance[KEY_SLOT(k[i + 1])];
    } else if (i > 0 && KEY_FRONT(k[i - 1])) {
      r = radiance[KEY_SLOT(k[i - 1])];
    }
    r.w = 0.0f;
    seen[v[i]] = r;
  }
}

/* gathered[p] = what patch p's crossings see, added in emit order; hits[p] = their number.
 * Nothing is written when the spans or the crossings did not fit. */
__kernel void wide_sum_patches(uint n, uint batch, __global const SiradBundle* restrict bundles,
                               __global const uint* restrict span_start, uint span_cap,
                               __global const uint* restrict cross_start, __global const uint* restrict line_start,
                               uint cross_cap, __global const float4* restrict seen, __global float4* restrict gathered,
                               __global uint* restrict hits) {
  uint p = get_global_id(0);
  const uint patches = n * batch;
  if (p >= patches) return;
  const uint lines = (uint)bundles[0].grid * (uint)bundles[0].grid * batch;
  if (span_start[patches] > span_cap || line_start[lines] > cross_cap) return;
  uint a = cross_start[span_start[p]], e = cross_start[span_start[p + 1]];
  float4 sum = (float4)(0.0f);
  for (uint i = a; i < e; ++i) sum += seen[i];
  gathered[p] = sum;
  hits[p] = e - a;
}
