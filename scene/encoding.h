// sirad: a scene as bytes, for sending it to nodes (SCENE messages, proto/PROTOCOL.md 3.1).
// Nodes mesh the decoded scene themselves (meshing is deterministic) and check the content
// hash of the result against the run's, so no patch data is taken on trust.
#pragma once
#include <string>
#include <string_view>

#include "scene/scene.h"

namespace sirad {

// "sirad-scene-v1", then little-endian counts and arrays: materials (name, reflectance,
// emission), triangles (3 vertices, material, source line), background, optional camera; or
// "sirad-scene-v2", the same with a flags word after each triangle (bit 0: Triangle::unlit,
// bit 1: Triangle::in_gap), written only for a scene that has a flag set.
std::string encode_scene(const Scene& scene);

// The inverse; every count, index and value is checked (finite coordinates, reflectance in
// [0, 1], finite non-negative emission, at least one triangle and one emitter). Throws
// sirad::Error naming `label` and the problem.
Scene decode_scene(std::string_view bytes, const std::string& label);

// The XXH3-128 of encoded scene bytes, as 32 lower-case hex digits: the name a scene goes by
// before it is meshed (Run.scene_source, Hello.scene_hashes; a node's scene cache).
std::string scene_bytes_hash(std::string_view bytes);
// True for what scene_bytes_hash writes: 32 lower-case hex digits.
bool is_scene_hash(std::string_view s);

}  // namespace sirad
