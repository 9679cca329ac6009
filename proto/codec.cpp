// sirad: the SIRAD/1 codec: frames <-> messages, with the structural checks of PROTOCOL.md.
#include "proto/codec.h"

#include <cstdio>

#include <fmt/format.h>
#include <google/protobuf/stubs/logging.h>

namespace sirad::proto {

namespace {

// protobuf logs to stderr every string field it refuses for invalid UTF-8 (and other parse
// trouble); decode reports every refusal itself as a ProtocolError, which its caller logs once,
// so a hostile peer must not be able to flood the log (a 60 s fuzz run printed 24,889 lines).
// Only protobuf's fatal errors still print.
void protobuf_log(google::protobuf::LogLevel level, const char* file, int line, const std::string& message) {
  if (level == google::protobuf::LOGLEVEL_FATAL) std::fprintf(stderr, "protobuf: %s:%d: %s\n", file, line, message.c_str());
}
[[maybe_unused]] const bool kQuietProtobuf = (google::protobuf::SetLogHandler(&protobuf_log), true);

[[noreturn]] void refuse(const std::string& why) { throw ProtocolError(why); }

bool known(uint8_t c) {
  switch (static_cast<Command>(c)) {
    case Command::hello: case Command::welcome: case Command::scene: case Command::ready:
    case Command::grant: case Command::report: case Command::update: case Command::stop:
    case Command::final_state: case Command::heartbeat: case Command::bye: case Command::error:
    case Command::image: case Command::tiles: case Command::pixels:
      return true;
  }
  return false;
}

// The header type each command carries (PROTOCOL.md section 3, table).
Header empty_header(Command c) {
  switch (c) {
    case Command::hello: return wire::Hello{};
    case Command::welcome: return wire::Welcome{};
    case Command::scene: return wire::SceneChunk{};
    case Command::ready: return wire::Ready{};
    case Command::grant: case Command::tiles: return wire::Grant{};
    case Command::image: return wire::Image{};
    case Command::pixels: return wire::Pixels{};
    case Command::report: case Command::final_state: return wire::Report{};
    case Command::update: return wire::Update{};
    case Command::stop: return wire::Stop{};
    case Command::error: return wire::Error{};
    case Command::heartbeat: case Command::bye: return std::monostate{};
  }
  return std::monostate{};
}

// Chunk sums: one frame per chunk, a whole number of (r, g, b) doubles, counts beside them.
template <typename T>
void check_chunk_frames(const T& h, const std::vector<std::string>& bulk, const char* what) {
  if (static_cast<std::size_t>(h.chunks_size()) > kMaxChunks)
    refuse(fmt::format("{}: {} chunks (at most {})", what, h.chunks_size(), kMaxChunks));
  if (h.counts_size() != h.chunks_size())
    refuse(fmt::format("{}: {} chunks but {} counts", what, h.chunks_size(), h.counts_size()));
  if (bulk.size() != static_cast<std::size_t>(h.chunks_size()))
    refuse(fmt::format("{}: {} chunks but {} bulk frames", what, h.chunks_size(), bulk.size()));
  for (std::size_t i = 0; i < bulk.size(); ++i)
    if (bulk[i].size() % (3 * sizeof(double)) != 0)
      refuse(fmt::format("{}: chunk frame {} has {} bytes, not whole (r, g, b) doubles", what, i, bulk[i].size()));
}

}  // namespace

const char* command_name(Command c) {
  switch (c) {
    case Command::hello: return "HELLO";
    case Command::welcome: return "WELCOME";
    case Command::scene: return "SCENE";
    case Command::ready: return "READY";
    case Command::grant: return "GRANT";
    case Command::report: return "REPORT";
    case Command::update: return "UPDATE";
    case Command::stop: return "STOP";
    case Command::final_state: return "FINAL";
    case Command::heartbeat: return "HEARTBEAT";
    case Command::bye: return "BYE";
    case Command::image: return "IMAGE";
    case Command::tiles: return "TILES";
    case Command::pixels: return "PIXELS";
    case Command::error: return "ERROR";
  }
  return "?";
}

std::vector<std::string> encode(const Message& m) {
  std::vector<std::string> frames;
  frames.reserve(3 + m.bulk.size());
  frames.emplace_back(kSignature);
  frames.emplace_back(1, static_cast<char>(m.command));
  std::string header;
  std::visit([&](const auto& h) {
    if constexpr (!std::is_same_v<std::decay_t<decltype(h)>, std::monostate>) h.SerializeToString(&header);
  }, m.header);
  frames.push_back(std::move(header));
  frames.insert(frames.end(), m.bulk.begin(), m.bulk.end());
  return frames;
}

MessageBound message_bound(uint8_t command, std::size_t patches, std::size_t chunks) {
  constexpr std::size_t envelope = kSignature.size() + 1 + kMaxHeaderBytes;  // frames 0 to 2
  switch (static_cast<Command>(command)) {
    case Command::report:
    case Command::update:
    case Command::final_state:
      return {3 + std::min(chunks, kMaxChunks), envelope + 24 * patches};
    case Command::scene: return {4, envelope + kMaxSceneFrameBytes};
    case Command::image: return {4, envelope + 24 * patches};
    case Command::pixels: return {3 + kMaxTilesPerGrant, envelope + kMaxTilesPerGrant * kMaxTileSide * kMaxTileSide * kPixelBytes};
    default: return {3, envelope};
  }
}

Message decode(const std::vector<std::string>& frames) {
  if (frames.size() < 3) refuse(fmt::format("truncated message: {} frames (at least 3)", frames.size()));
  if (frames[0] != kSignature) {
    std::string shown = frames[0].substr(0, 16);
    for (char& c : shown)
      if (c < 0x20 || c > 0x7e) c = '?';
    refuse(fmt::format("wrong protocol signature '{}' (expected {})", shown, kSignature));
  }
  if (frames[1].size() != 1) refuse(fmt::format("command frame of {} bytes (expected 1)", frames[1].size()));
  const uint8_t byte = static_cast<uint8_t>(frames[1][0]);
  if (!known(byte)) refuse(fmt::format("unknown command 0x{:02x}", byte));
  Message m;
  m.command = static_cast<Command>(byte);
  const char* what = command_name(m.command);
  if (frames[2].size() > kMaxHeaderBytes)
    refuse(fmt::format("{}: header of {} bytes (at most {})", what, frames[2].size(), kMaxHeaderBytes));
  m.header = empty_header(m.command);
  bool parsed = std::visit([&](auto& h) {
    if constexpr (std::is_same_v<std::decay_t<decltype(h)>, std::monostate>) return frames[2].empty();
    else return h.ParseFromString(frames[2]);
  }, m.header);
  if (!parsed) refuse(fmt::format("{}: header does not parse", what));
  m.bulk.assign(frames.begin() + 3, frames.end());

  switch (m.command) {
    case Command::report: case Command::final_state:
      check_chunk_frames(std::get<wire::Report>(m.header), m.bulk, what);
      break;
    case Command::update:
      check_chunk_frames(std::get<wire::Update>(m.header), m.bulk, what);
      break;
    case Command::scene: {
      const auto& h = std::get<wire::SceneChunk>(m.header);
      if (m.bulk.size() != 1) refuse(fmt::format("SCENE: {} bulk frames (expected 1)", m.bulk.size()));
      if (m.bulk[0].size() > kMaxSceneFrameBytes)
        refuse(fmt::format("SCENE: frame of {} bytes (at most {})", m.bulk[0].size(), kMaxSceneFrameBytes));
      if (h.offset() > h.total_bytes() || m.bulk[0].size() > h.total_bytes() - h.offset())
        refuse(fmt::format("SCENE: bytes {}..{} beyond the scene's {}", h.offset(), h.offset() + m.bulk[0].size(),
                           h.total_bytes()));
      break;
    }
    case Command::image:
      if (m.bulk.size() != 1) refuse(fmt::format("IMAGE: {} bulk frames (expected 1)", m.bulk.size()));
      if (m.bulk[0].size() % (3 * sizeof(double)) != 0)
        refuse(fmt::format("IMAGE: solution frame of {} bytes, not whole (r, g, b) doubles", m.bulk[0].size()));
      break;
    case Command::pixels: {
      uint64_t tiles = 0;
      for (const wire::Range& r : std::get<wire::Pixels>(m.header).done()) {
        if (r.last() <= r.first()) refuse(fmt::format("PIXELS: empty range [{}, {})", r.first(), r.last()));
        if (r.last() - r.first() > kMaxTilesPerGrant - tiles) refuse(fmt::format("PIXELS: more than {} tiles", kMaxTilesPerGrant));
        tiles += r.last() - r.first();
      }
      if (m.bulk.size() != tiles) refuse(fmt::format("PIXELS: {} tiles but {} bulk frames", tiles, m.bulk.size()));
      for (std::size_t i = 0; i < m.bulk.size(); ++i)
        if (m.bulk[i].empty() || m.bulk[i].size() % kPixelBytes != 0)
          refuse(fmt::format("PIXELS: tile frame {} has {} bytes, not whole pixels of {} bytes", i, m.bulk[i].size(), kPixelBytes));
      break;
    }
    default:
      if (!m.bulk.empty()) refuse(fmt::format("{}: {} unexpected bulk frames", what, m.bulk.size()));
  }
  return m;
}

}  // namespace sirad::proto
