// sirad fuzzing: the SIRAD/1 decoder (proto/codec.h) on arbitrary frames. Shared by the
// libFuzzer target (decode_fuzz.cpp, built with -DSIRAD_FUZZ=ON and clang) and the corpus
// replay in the unit tests (fuzz_corpus_test.cpp), so every CI run replays the corpus through
// the same code the fuzzer ran.
//
// An input is a sequence of frames, each a 2-byte little-endian length and that many bytes (a
// length past the end takes what is left); at most 64 frames. decode must either refuse the
// frames with a ProtocolError or return a message that encodes and decodes back to itself.
#pragma once
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "proto/codec.h"

namespace sirad::proto::fuzz {

inline std::vector<std::string> frames_of(const uint8_t* data, std::size_t size) {
  std::vector<std::string> frames;
  std::size_t at = 0;
  while (at + 2 <= size && frames.size() < 64) {
    std::size_t n = static_cast<std::size_t>(data[at]) | static_cast<std::size_t>(data[at + 1]) << 8;
    at += 2;
    n = std::min(n, size - at);
    frames.emplace_back(reinterpret_cast<const char*>(data + at), n);
    at += n;
  }
  return frames;
}

// The inverse, for writing a corpus (frames over 65535 bytes do not fit; the caller keeps
// its samples small).
inline std::string bytes_of(const std::vector<std::string>& frames) {
  std::string out;
  for (const std::string& f : frames) {
    if (f.size() > 0xffff) throw std::length_error("fuzz: frame over 65535 bytes");
    out.push_back(static_cast<char>(f.size() & 0xff));
    out.push_back(static_cast<char>(f.size() >> 8));
    out += f;
  }
  return out;
}

inline std::string serialised(const Header& h) {
  std::string s;
  std::visit([&](const auto& v) {
    if constexpr (!std::is_same_v<std::decay_t<decltype(v)>, std::monostate>) v.SerializeToString(&s);
  }, h);
  return s;
}

enum class Outcome { refused, accepted };

// Decodes one input. Throws std::logic_error if an accepted message does not survive
// encode -> decode unchanged (command, header and bulk); any other exception than
// ProtocolError escapes as the bug it is.
inline Outcome decode_one(const uint8_t* data, std::size_t size) {
  std::vector<std::string> frames = frames_of(data, size);
  Message m;
  try {
    m = decode(frames);
  } catch (const ProtocolError&) {
    return Outcome::refused;
  }
  Message back = decode(encode(m));
  if (back.command != m.command || back.header.index() != m.header.index() ||
      serialised(back.header) != serialised(m.header) || back.bulk != m.bulk)
    throw std::logic_error("fuzz: a decoded message does not survive encode and decode");
  return Outcome::accepted;
}

}  // namespace sirad::proto::fuzz
