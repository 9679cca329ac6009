// sirad: a baked lightmap's files (render/bake.h), for engines and for any glTF viewer.
//   - NAME-lightmap.exr: half-float linear radiance leaving each texel's surface (the light a
//     camera sees there: emission plus the reflected light, the material's reflectance in it),
//     the sum unprefixed (R, G, B) and the layers direct, indirect and error (the estimate of
//     each texel's standard error, render/bake.h), and coverage (R = G = B: the share of the
//     texel's samples kept; 0 where its value was filled from its neighbours: a gutter, or a
//     face's part inside a solid or under a rug, which no camera sees). Rows top first; texel (x, y) is at
//     TEXCOORD_1 ((x + 0.5) / width, (y + 0.5) / height).
//   - NAME-lightmap.png: its tone map (times 2^exposure, clamped, sRGB), as the images' PNG.
//   - NAME-baked.glb: the scene's faces (one mesh per object, one primitive per material) with
//     the atlas's UV as TEXCOORD_1 (the lightmap channel engines read: Unity's UV2, Godot's
//     UV2, three.js's lightMap channel 1) and as TEXCOORD_0 too, and the PNG embedded. Each
//     material is KHR_materials_unlit with the PNG as its base colour texture (TEXCOORD_0): any
//     viewer (three.js, Blender's Eevee and Cycles, Godot) shows the baked light as it is, with
//     no lights of its own. Engines that light their own materials take the lightmap from
//     TEXCOORD_1 and the EXR the asset's extras name (sirad_lightmap), dividing by the
//     reflectance (each material's extras: sirad_reflectance) where they want irradiance.
//     Both sides of a two-sided face are faces of their own, pulled kSidesApart of the scene's
//     radius apart along their normals, each one-sided with its own texels (io/write_gltf.h).
// Every file is written atomically.
#pragma once
#include <string>

#include "io/write.h"
#include "render/bake.h"
#include "scene/atlas.h"
#include "scene/scene.h"

namespace sirad {

struct LightmapFiles {
  std::string exr, png, glb;
};

// Writes NAME-lightmap.exr, NAME-lightmap.png and NAME-baked.glb of `lightmap`, baked on `atlas`
// of `scene`; `camera` (if any) becomes the glb's camera node of that aspect. Throws
// sirad::Error for a lightmap not of the atlas, or one that half floats cannot hold.
LightmapFiles write_lightmap(const std::string& name, const Scene& scene, const Atlas& atlas, const Lightmap& lightmap,
                             float exposure, const Camera* camera, double aspect, const Attributes& attributes);

}  // namespace sirad
