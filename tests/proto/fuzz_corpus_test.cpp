// sirad tests: the decoder's fuzz corpus (tests/fuzz/corpus) replays on every CI run through the
// code the fuzzer runs (fuzz/decode_fuzz.h): no input may crash, throw anything but a
// refusal, or decode to a message that does not survive encode and decode. The corpus holds one
// real message of every type (written by CorpusHoldsEveryMessageType when
// SIRAD_WRITE_FUZZ_CORPUS names a directory), and the fuzzer's finds worth keeping.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>

#include <gtest/gtest.h>

#include "tests/fuzz/decode_fuzz.h"
#include "tests/proto_samples.h"

namespace sirad::proto {
namespace {

namespace fs = std::filesystem;
const fs::path kCorpus = fs::path(SIRAD_SOURCE_DIR) / "tests" / "fuzz" / "corpus";

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(FuzzCorpus, EveryInputIsRefusedOrRoundTrips) {
  ASSERT_TRUE(fs::is_directory(kCorpus)) << kCorpus;
  int files = 0, accepted = 0;
  for (const auto& e : fs::directory_iterator(kCorpus)) {
    std::string bytes = slurp(e.path());
    SCOPED_TRACE(e.path().filename().string());
    auto outcome = fuzz::decode_one(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    accepted += outcome == fuzz::Outcome::accepted;
    ++files;
  }
  EXPECT_GE(files, 12);
  EXPECT_GE(accepted, 12);  // the real messages are in it and decode
}

// Every message type has its real message in the corpus, byte for byte as encode makes it.
TEST(FuzzCorpus, CorpusHoldsEveryMessageType) {
  if (const char* dir = std::getenv("SIRAD_WRITE_FUZZ_CORPUS")) {
    for (const Message& m : test::one_of_each()) {
      std::ofstream out(fs::path(dir) / (std::string("real-") + command_name(m.command)), std::ios::binary);
      out << fuzz::bytes_of(encode(m));
    }
  }
  for (const Message& m : test::one_of_each()) {
    fs::path p = kCorpus / (std::string("real-") + command_name(m.command));
    ASSERT_TRUE(fs::exists(p)) << p;
    EXPECT_EQ(slurp(p), fuzz::bytes_of(encode(m))) << p;
  }
}

// The frame format itself: lengths, a short tail, the 64-frame cap.
TEST(FuzzCorpus, FramesOfSplitsLikeBytesOfJoins) {
  std::vector<std::string> frames = {"SIRAD1", std::string(1, '\x0a'), "", std::string(300, 'x')};
  std::string bytes = fuzz::bytes_of(frames);
  EXPECT_EQ(fuzz::frames_of(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()), frames);
  std::string cut = bytes.substr(0, bytes.size() - 100);
  auto short_tail = fuzz::frames_of(reinterpret_cast<const uint8_t*>(cut.data()), cut.size());
  ASSERT_EQ(short_tail.size(), 4u);
  EXPECT_EQ(short_tail.back().size(), 200u);
  std::string many(2 * 100, '\0');  // 100 empty frames
  EXPECT_EQ(fuzz::frames_of(reinterpret_cast<const uint8_t*>(many.data()), many.size()).size(), 64u);
}

}  // namespace
}  // namespace sirad::proto
