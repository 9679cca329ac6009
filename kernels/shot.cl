/* sirad: the first shot's view from a point on an emitter (DESIGN.md section 1, "first shot"),
 * rendered with the rasterisation machinery of bundle.cl (set_edge, covers, row_span,
 * FOR_EACH_COVERED, depth_at), which the host prepends together with bundle_types.h and
 * shot_types.h. Per shot it enqueues:
 *   shot_vertices (runs of vertices) every vertex into the five faces' coordinates, with an
 *                 outcode per face (which side of the face's pyramid it is on);
 *   project_shot  (runs of patches)  every patch of a block into the five hemicube faces: clipped
 *                 against z >= near_z (a triangle becomes 0, 1 or 2 triangles), projected
 *                 (X, Y) = (x / z, y / z) scaled, counter-clockwise, with the plane of 1 / z
 *                 (affine in X, Y for a planar patch) as its depth;
 *   raster_shot   (one work-item per band of a face's rows)  a z-buffer over the band's pixel
 *                 samples, triangle by triangle: the nearest patch at each sample (largest
 *                 1 / z; back faces occlude too) and, if its front faces the eye, its index in
 *                 the image.
 * The patches go through the last two in blocks of consecutive patches (the host's block
 * size), in patch order, the z-buffers kept from block to block: every sample meets the
 * triangles in the same order as in one pass, so the image is the same bit for bit, and the
 * scratch is a block's, not the mesh's.
 * The host turns the image into form factors (kernels decide visibility only; the weights and
 * sums are the host's, in double). Each image element has one writer; no atomics.
 */

/* Face f's coordinates of a vertex relative to the bounding-sphere centre. */
SIRAD_INLINE float3 shot_face_point(__constant SiradShot* s, int f, float4 q) {
  __constant const float* ax = s->axes + 9 * f;
  float px = q.x - s->eye[0], py = q.y - s->eye[1], pz = q.z - s->eye[2];
  return (float3)(px * ax[0] + py * ax[1] + pz * ax[2], px * ax[3] + py * ax[4] + pz * ax[5],
                  px * ax[6] + py * ax[7] + pz * ax[8]);
}

/* Where edge a-b meets the plane z = near, computed from the endpoint with the smaller vertex
 * index, so that two patches sharing the edge get the same point bit for bit. */
SIRAD_INLINE float3 shot_clip_point(float3 a, uint ia, float3 b, uint ib, float near_z) {
  if (ib < ia) {
    float3 t = a;
    a = b;
    b = t;
  }
  float t = (near_z - a.z) / (b.z - a.z);
  return (float3)(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), near_z);
}

/* One projected triangle of face f, or an empty one (rows that no band lets through). */
/* `plane` = (z0, dzdx, dzdy): 1 / z of the patch's plane as an affine function of the pixel
 * coordinates, anchored at the face centre (offset_x, offset_y): computed once per patch and
 * face from the unclipped patch (shot_plane), so that a near-plane clip point never anchors it
 * and both faces of a thin wall get the same plane to rounding. */
SIRAD_INLINE void shot_triangle(__constant SiradShot* s, int f, float3 q0, float3 q1, float3 q2,
                                float3 plane, __global SiradProjected* out, __global int2* out_rows) {
  float X0 = q0.x / q0.z * s->scale + s->offset_x, Y0 = q0.y / q0.z * s->scale + s->offset_y;
  float X1 = q1.x / q1.z * s->scale + s->offset_x, Y1 = q1.y / q1.z * s->scale + s->offset_y;
  float X2 = q2.x / q2.z * s->scale + s->offset_x, Y2 = q2.y / q2.z * s->scale + s->offset_y;
  float area2 = edge_raw(X0, Y0, X1, Y1, X2, Y2);
  /* Seen from the eye, a patch whose front faces it turns clockwise: the signed area of the
   * projection has the sign of q0 . n (see DESIGN.md's note on the first shot). Store it
   * counter-clockwise and keep "faces the eye" in the FRONT bit. */
  bool faces_eye = area2 < 0.0f;
  float x1 = faces_eye ? X2 : X1, y1 = faces_eye ? Y2 : Y1;
  float x2 = faces_eye ? X1 : X2, y2 = faces_eye ? Y1 : Y2;
  SiradProjected p;
  p.flags = faces_eye ? SIRAD_FRONT_POS : 0u;
  set_edge(&p, 0, X0, Y0, x1, y1);
  set_edge(&p, 1, x1, y1, x2, y2);
  set_edge(&p, 2, x2, y2, X0, Y0);
  p.x0 = s->offset_x;
  p.y0 = s->offset_y;
  p.xmin = fmin(X0, fmin(x1, x2));
  p.xmax = fmax(X0, fmax(x1, x2));
  p.pad = 0u;
  float a = fabs(area2);
  int first_row = f == 0 ? 0 : s->resolution / 2;
  if (!(a > 0.0f) || !(p.xmax >= 0.0f) || !(p.xmin <= (float)(s->resolution - 1))) {
    p.z0 = p.dzdx = p.dzdy = 0.0f;
    p.rows[0] = 0x7fffffff;
    p.rows[1] = -0x7fffffff;
  } else {
    p.z0 = plane.x;
    p.dzdx = plane.y;
    p.dzdy = plane.z;
    float ylo = fmin(Y0, fmin(y1, y2)), yhi = fmax(Y0, fmax(y1, y2));
    p.rows[0] = (int)ceil(fmax(ylo, (float)first_row));
    p.rows[1] = (int)floor(fmin(yhi, (float)(s->resolution - 1)));
  }
  *out = p;
  *out_rows = (int2)(p.rows[0], p.rows[1]);
}

/* The plane of the unclipped patch q0 q1 q2 (face coordinates): N . q = d. Along the pixel ray
 * q = z (u, v, 1), u = (X - offset_x) / scale, v = (Y - offset_y) / scale, it gives
 * 1 / z = (N.x u + N.y v + N.z) / d. d = 0 (the plane through the eye: seen edge-on) gives a
 * zero plane; such a patch covers no pixel sample's area anyway. */
SIRAD_INLINE float3 shot_plane(__constant SiradShot* s, float3 q0, float3 q1, float3 q2) {
  float3 n = cross(q1 - q0, q2 - q0);
  float d = dot(n, q0);
  if (d == 0.0f) return (float3)(0.0f);
  return (float3)(n.z / d, n.x / (d * s->scale), n.y / (d * s->scale));
}

SIRAD_INLINE void shot_empty(__global SiradProjected* out, __global int2* out_rows) {
  out->rows[0] = 0x7fffffff;
  out->rows[1] = -0x7fffffff;
  *out_rows = (int2)(0x7fffffff, -0x7fffffff);
}

/* Every vertex in the five faces' coordinates, once per shot (a vertex is shared by ~6 patch
 * corners): face_coords[5 v + f] = (x, y, z, outcode) with outcode bits 1: x > z, 2: x < -z,
 * 4: y > z, 8: y < -z on face 0 and y < 0 on the side faces (below the horizon), 16: z < near.
 * Work-item i takes vertices [i * per_item, (i + 1) * per_item). */
__kernel void shot_vertices(__global const float4* vertices, uint vertex_count, uint per_item,
                            __constant SiradShot* s, __global float4* face_coords) {
  uint last = min((uint)get_global_id(0) * per_item + per_item, vertex_count);
  for (uint v = get_global_id(0) * per_item; v < last; ++v) {
    float4 p = vertices[v];
    for (int f = 0; f < 5; ++f) {
      float3 q = shot_face_point(s, f, p);
      uint code = (q.x > q.z ? 1u : 0u) | (q.x < -q.z ? 2u : 0u) | (q.y > q.z ? 4u : 0u) |
                  ((f == 0 ? q.y < -q.z : q.y < 0.0f) ? 8u : 0u) | (q.z >= s->near_z ? 0u : 16u);
      face_coords[5 * (size_t)v + f] = (float4)(q.x, q.y, q.z, (float)code);  /* exact: code < 32 */
    }
  }
}

/* The block of patches [first, first + count). Slots: triangle t (0 or 1) of patch first + j in
 * face f is projected[(f * count + j) * 2 + t]. Work-item i takes the block's patches
 * [i * per_item, (i + 1) * per_item). */
__kernel void project_shot(__global const float4* face_coords, __global const uint4* patches,
                           uint first, uint count, uint per_item, __constant SiradShot* s,
                           __global SiradProjected* projected, __global int2* rows) {
  uint last = min((uint)get_global_id(0) * per_item + per_item, count);
  const float near_z = s->near_z;
  for (uint j = get_global_id(0) * per_item; j < last; ++j) {
    uint4 idx = patches[first + j];
    uint id[3] = {idx.x, idx.y, idx.z};
    for (int f = 0; f < 5; ++f) {
      size_t slot = ((size_t)f * count + j) * 2;
      float4 c0 = face_coords[5 * (size_t)idx.x + f], c1 = face_coords[5 * (size_t)idx.y + f],
             c2 = face_coords[5 * (size_t)idx.z + f];
      uint o0 = (uint)c0.w, o1 = (uint)c1.w, o2 = (uint)c2.w;
      /* Entirely beyond one side of the face's pyramid |x| <= z, |y| <= z (a half-space through
       * the eye, convex, so the whole triangle is there), below the horizon on a side face (only
       * y > 0 is rendered there), or behind the near plane: no pixel sample can see it. */
      bool outside = (o0 & o1 & o2) != 0u;
      int inside = 3 - (int)((o0 >> 4) & 1u) - (int)((o1 >> 4) & 1u) - (int)((o2 >> 4) & 1u);
      float3 q[3] = {c0.xyz, c1.xyz, c2.xyz};
      if (inside == 0 || outside) {
        shot_empty(projected + slot, rows + slot);
        shot_empty(projected + slot + 1, rows + slot + 1);
        continue;
      }
      float3 plane = shot_plane(s, q[0], q[1], q[2]);
      if (inside == 3) {
        shot_triangle(s, f, q[0], q[1], q[2], plane, projected + slot, rows + slot);
        shot_empty(projected + slot + 1, rows + slot + 1);
        continue;
      }
      /* Sutherland-Hodgman against z >= near: keeps the order of the vertices, so the
       * clipped polygon (3 or 4 vertices) turns the way the patch did. */
      float3 poly[4];
      int m = 0;
      for (int k = 0; k < 3; ++k) {
        int k1 = (k + 1) % 3;
        bool in0 = q[k].z >= near_z, in1 = q[k1].z >= near_z;
        if (in0) poly[m++] = q[k];
        if (in0 != in1) poly[m++] = shot_clip_point(q[k], id[k], q[k1], id[k1], near_z);
      }
      shot_triangle(s, f, poly[0], poly[1], poly[2], plane, projected + slot, rows + slot);
      if (m == 4) shot_triangle(s, f, poly[0], poly[2], poly[3], plane, projected + slot + 1, rows + slot + 1);
      else shot_empty(projected + slot + 1, rows + slot + 1);
    }
  }
}

/* One band of one face's rows, for the block of patches [first, first + count) as
 * project_shot left it. Bands 0 .. bands_top - 1 split face 0's rows [0, H); then each side
 * face has bands_side bands over its rows [H / 2, H). Scratch per band: band_list (capacity
 * triangle slots of the face reaching the band), zbuf and zwin (the band's rows of H pixel
 * samples: nearest 1 / z, and the patch index with bit 31 set when its front faces the eye),
 * cleared by the first block (stage bit 1) and kept for the next. image (written by the last
 * block, stage bit 2): face 0's H x H samples, then faces 1..4's H / 2 x H each, row-major; an
 * element is the patch index, or SIRAD_NO_PATCH. band_stats[band] = the most triangles of one
 * block reaching the band (also when they do not fit, so the host can grow the scratch and
 * render the shot again). */
__kernel void raster_shot(__global const SiradProjected* restrict projected,
                          __global const int2* restrict rows, uint first, uint count, uint stage,
                          __constant SiradShot* s, __global uint* restrict band_list,
                          __global float* restrict zbuf, __global uint* restrict zwin,
                          __global uint* restrict image, __global uint* restrict band_stats) {
  int band = get_global_id(0);
  const int H = s->resolution, half_h = H / 2, rpb = s->rows_per_band;
  if (band >= s->bands_top + 4 * s->bands_side) return;
  int f, r0;
  if (band < s->bands_top) {
    f = 0;
    r0 = band * rpb;
  } else {
    int k = band - s->bands_top;
    f = 1 + k / s->bands_side;
    r0 = half_h + (k % s->bands_side) * rpb;
  }
  const int r1 = min(r0 + rpb, H);
  const uint cap = s->capacity;
  band_list += (size_t)band * cap;
  zbuf += (size_t)band * rpb * H;
  zwin += (size_t)band * rpb * H;
  __global const SiradProjected* face = projected + (size_t)f * count * 2;
  __global const int2* face_rows = rows + (size_t)f * count * 2;

  if (stage & 1u) {
    /* The band's z-buffer holds all its rows: each listed triangle is drawn over the rows it
     * covers at once (no per-row scan of the whole list); a sample still sees the triangles in
     * list order, so the result is the same as drawing row by row. */
    for (int i = 0; i < (r1 - r0) * H; ++i) {
      zbuf[i] = 0.0f;
      zwin[i] = SIRAD_NO_PATCH;
    }
    band_stats[band] = 0u;
  }
  uint listed = 0;
  for (uint t = 0; t < 2 * count; ++t) {
    int2 r = face_rows[t];
    if (r.y < r0 || r.x >= r1) continue;
    if (listed < cap) band_list[listed] = t;
    ++listed;
  }
  band_stats[band] = max(band_stats[band], listed);
  if (listed > cap) return;

  const float tie = s->depth_tie;
  __global uint* out = image + (f == 0 ? (size_t)0 : (size_t)H * H + (size_t)(f - 1) * half_h * H);
  const int out_row0 = f == 0 ? 0 : half_h;
  for (uint i = 0; i < listed; ++i) {
    uint t = band_list[i];
    int2 r = face_rows[t];
    SiradProjected p = face[t];
    uint tag = (first + (t >> 1)) | ((p.flags & SIRAD_FRONT_POS) ? 0x80000000u : 0u);
    const int ylo = max(r.x, r0), yhi = min(r.y, r1 - 1);
    for (int y = ylo; y <= yhi; ++y) {
      __global float* zrow = zbuf + (size_t)(y - r0) * H;
      __global uint* wrow = zwin + (size_t)(y - r0) * H;
      FOR_EACH_COVERED(&p, y, H, x) {
        float w = depth_at(&p, x, y);
        uint old = wrow[x];
        bool take;
        if (old == SIRAD_NO_PATCH) {
          take = true;
        } else {
          float wo = zrow[x];
          /* Two faces at one place (DESIGN.md section 1, "Coincident faces"): one facing the
           * eye is seen before one facing away (a thin wall's two sides), and of two facing
           * the same way the later patch (triangles are listed in patch order) is on top.
           * Otherwise the nearer (larger 1 / z) is seen. */
          if (fabs(w - wo) <= tie * fmax(w, wo)) take = (tag & 0x80000000u) || !(old & 0x80000000u);
          else take = w > wo;
        }
        if (take) {
          zrow[x] = w;
          wrow[x] = tag;
        }
      }
    }
  }
  if (!(stage & 2u)) return;
  for (int y = r0; y < r1; ++y) {
    __global const uint* wrow = zwin + (size_t)(y - r0) * H;
    __global uint* o = out + (size_t)(y - out_row0) * H;
    for (int x = 0; x < H; ++x) {
      uint tag = wrow[x];
      o[x] = (tag != SIRAD_NO_PATCH && (tag & 0x80000000u)) ? (tag & 0x7fffffffu) : SIRAD_NO_PATCH;
    }
  }
}
