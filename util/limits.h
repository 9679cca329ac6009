// sirad: the size limits that more than one part of sirad enforces, in one place. Each bounds
// what a file, a message or a request may make a process read or hold, whatever it claims
// about itself. Limits that one part alone enforces live beside their code (the run settings'
// in cluster/settings.h, the wire's in proto/codec.h, the job files' in cluster/jobs.h).
#pragma once
#include <cstddef>

namespace sirad {

// A scene file as read (OBJ, MTL, glTF, PLY, a solution read back): 2 GiB.
inline constexpr std::size_t kMaxInputFileBytes = std::size_t{1} << 31;
// An encoded scene (scene/encoding.h): the SCENE a node receives and keeps in its cache, the
// scene of a farm's job: 2 GiB.
inline constexpr std::size_t kMaxSceneBytes = std::size_t{1} << 31;
// What of a peer's own words (an ERROR's reason, a name) goes into a log line or an error.
inline constexpr std::size_t kPeerTextBytes = 300;

}  // namespace sirad
