// sirad: the SIRAD/1 codec (proto/PROTOCOL.md): a message as ZeroMQ frames, and back.
// Constants mirror the spec's section 3; decode refuses anything the spec calls malformed
// (section 5) with a ProtocolError whose text is one line naming the reason.
#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "sirad.pb.h"  // generated from proto/sirad.proto

namespace sirad::proto {

inline constexpr std::string_view kSignature = "SIRAD1";  // frame 0, every message
inline constexpr std::size_t kMaxHeaderBytes = 64 * 1024;  // section 6
inline constexpr std::size_t kMaxSceneFrameBytes = 4 * 1024 * 1024;
inline constexpr std::size_t kMaxChunks = 4096;
// The image phase (section 3.4): a tile's side, and the tiles of one TILES grant, at most.
inline constexpr uint32_t kMaxTileSide = 64;
inline constexpr std::size_t kMaxTilesPerGrant = 16;
inline constexpr std::size_t kPixelBytes = 9 * sizeof(float);  // direct, indirect, combined rgb

enum class Command : uint8_t {
  hello = 0x01,
  welcome = 0x02,
  scene = 0x03,
  ready = 0x04,
  grant = 0x05,
  report = 0x06,
  update = 0x07,
  stop = 0x08,
  final_state = 0x09,
  heartbeat = 0x0A,
  bye = 0x0B,
  image = 0x0C,
  tiles = 0x0D,
  pixels = 0x0E,
  error = 0x0F,
};
const char* command_name(Command c);

using Header = std::variant<std::monostate, wire::Hello, wire::Welcome, wire::SceneChunk, wire::Ready,
                            wire::Grant, wire::Report, wire::Update, wire::Stop, wire::Error, wire::Image,
                            wire::Pixels>;

struct Message {
  Command command = Command::heartbeat;
  Header header;                   // the command's type (monostate for heartbeat, bye)
  std::vector<std::string> bulk;   // frames after the header
};

class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The most one message of a command may hold as its receiver reads it (frames and bytes in
// all, signature and command included), for a receiver whose run has `patches` patches in
// `chunks` chunks (0 and 0 without a run): REPORT, UPDATE and FINAL at most one frame per chunk
// and 24 bytes per patch in all; IMAGE one frame of 24 bytes per patch; SCENE one frame of
// kMaxSceneFrameBytes; PIXELS kMaxTilesPerGrant frames of kMaxTileSide^2 pixels; every other
// command its header alone. An unknown command byte gets the header-only bound (decode refuses it).
struct MessageBound {
  std::size_t frames = 0, bytes = 0;
};
MessageBound message_bound(uint8_t command, std::size_t patches, std::size_t chunks);

// The frames of a message: signature, command byte, serialised header, bulk frames.
std::vector<std::string> encode(const Message& message);

// Parses and checks frames: signature and version, a known command, a header of the command's
// type within the size limit, and the bulk frames the header announces (count; doubles for
// chunk sums and an image's solution; at most one scene frame of at most 4 MiB; one frame of
// whole pixels per tile done, at most kMaxTilesPerGrant). Sizes that depend on the run
// (patches per chunk, the solution's patches, a tile's pixels) are checked by the receiver's
// state machine.
Message decode(const std::vector<std::string>& frames);

}  // namespace sirad::proto
