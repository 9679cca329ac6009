// sirad tests: the SIRAD/1 codec against proto/PROTOCOL.md: every message type round-trips;
// truncated, oversized, wrong-version, wrong-type and inconsistent messages are refused with a
// one-line reason. Then the same frames over a real ZeroMQ ROUTER/DEALER pair.
#include <algorithm>
#include <chrono>
#include <cstring>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>

#include <gtest/gtest.h>
#include <zmq.hpp>

#include "proto/codec.h"
#include "proto/peer_bytes.h"
#include "proto/transport.h"
#include "tests/proto_samples.h"

namespace sirad::proto {
namespace {

using test::doubles;
using test::one_of_each;

std::string serialised(const Header& h) {
  std::string s;
  std::visit([&](const auto& v) {
    if constexpr (!std::is_same_v<std::decay_t<decltype(v)>, std::monostate>) v.SerializeToString(&s);
  }, h);
  return s;
}

TEST(ProtoCodec, EveryMessageTypeRoundTrips) {
  for (const Message& m : one_of_each()) {
    SCOPED_TRACE(command_name(m.command));
    auto frames = encode(m);
    ASSERT_GE(frames.size(), 3u);
    EXPECT_EQ(frames[0], "SIRAD1");
    Message back = decode(frames);
    EXPECT_EQ(back.command, m.command);
    EXPECT_EQ(back.header.index(), m.header.index());
    EXPECT_EQ(serialised(back.header), serialised(m.header));
    EXPECT_EQ(back.bulk, m.bulk);
  }
}

void expect_refused(const std::vector<std::string>& frames, const std::string& reason) {
  try {
    decode(frames);
    ADD_FAILURE() << "accepted; expected refusal: " << reason;
  } catch (const ProtocolError& e) {
    std::string what = e.what();
    EXPECT_NE(what.find(reason), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << "one line";
  }
}

TEST(ProtoCodec, MalformedMessagesAreRefusedWithAReason) {
  auto report = one_of_each()[5];
  auto good = encode(report);
  // Truncated: too few frames; a bulk frame cut short; a missing bulk frame.
  expect_refused({good[0], good[1]}, "truncated");
  auto cut = good;
  cut[4].resize(cut[4].size() - 3);
  expect_refused(cut, "not whole");
  auto missing = good;
  missing.pop_back();
  expect_refused(missing, "bulk frames");
  // Wrong version or protocol.
  auto old = good;
  old[0] = "SIRAD0";
  expect_refused(old, "signature");
  auto binary = good;
  binary[0] = std::string("\x00\xff\x01", 3);
  expect_refused(binary, "signature");
  // Wrong type: unknown command byte, a command frame of two bytes, a header of another type.
  auto unknown = good;
  unknown[1] = std::string(1, '\x42');
  expect_refused(unknown, "unknown command 0x42");
  auto wide = good;
  wide[1] = "\x06\x06";
  expect_refused(wide, "command frame");
  auto garbage = good;
  garbage[2] = std::string("\xff\xff\xff\xff\xff", 5);
  expect_refused(garbage, "does not parse");
  // Oversized header; counts that disagree with the chunks; bulk on a message that has none.
  auto huge = good;
  huge[2] = std::string(kMaxHeaderBytes + 1, '\0');
  expect_refused(huge, "header of");
  wire::Report r = std::get<wire::Report>(report.header);
  r.add_counts(1);
  expect_refused(encode({Command::report, r, report.bulk}), "counts");
  auto hb = encode({Command::heartbeat, std::monostate{}, {}});
  hb.push_back("x");
  expect_refused(hb, "unexpected bulk");
  auto hb_header = encode({Command::heartbeat, std::monostate{}, {}});
  hb_header[2] = "x";
  expect_refused(hb_header, "does not parse");
  // A scene frame beyond the announced size.
  wire::SceneChunk sc;
  sc.set_total_bytes(4);
  expect_refused(encode({Command::scene, sc, {std::string("12345")}}), "beyond");
}

// The image phase's messages (PROTOCOL.md section 3.4): IMAGE carries one solution frame of
// whole (r, g, b) doubles; PIXELS one frame of whole pixels per tile it names, at most
// kMaxTilesPerGrant of them, in ranges that are not empty (a range so long that its length
// would wrap the count is refused too).
TEST(ProtoCodec, ImageMessagesAreRefusedWhenTheirFramesDoNotFit) {
  const std::vector<Message> all = one_of_each();
  auto find = [&](Command c) { return *std::find_if(all.begin(), all.end(), [&](const Message& m) { return m.command == c; }); };
  const Message image = find(Command::image), pixels = find(Command::pixels);
  expect_refused(encode({Command::image, image.header, {}}), "IMAGE: 0 bulk frames");
  expect_refused(encode({Command::image, image.header, {doubles({1, 2})}}), "not whole");
  expect_refused(encode({Command::image, image.header, {doubles({1, 2, 3}), doubles({1, 2, 3})}}), "IMAGE: 2 bulk frames");
  expect_refused(encode({Command::pixels, pixels.header, {}}), "1 tiles but 0 bulk frames");
  expect_refused(encode({Command::pixels, pixels.header, {std::string(kPixelBytes + 1, '\0')}}), "not whole pixels");
  expect_refused(encode({Command::pixels, pixels.header, {std::string()}}), "not whole pixels");
  wire::Pixels p = std::get<wire::Pixels>(pixels.header);
  p.mutable_done(0)->set_last(p.done(0).first());
  expect_refused(encode({Command::pixels, p, pixels.bulk}), "empty range");
  p.mutable_done(0)->set_last(p.done(0).first() + kMaxTilesPerGrant + 1);
  expect_refused(encode({Command::pixels, p, pixels.bulk}), "more than 16 tiles");
  auto* wrap = p.add_done();  // 16 tiles, then a range of 2^64 - 16: the sum would wrap to 0
  p.mutable_done(0)->set_last(p.done(0).first() + kMaxTilesPerGrant);
  wrap->set_first(16);
  wrap->set_last(0);
  expect_refused(encode({Command::pixels, p, pixels.bulk}), "empty range");
  wrap->set_first(0);
  wrap->set_last(~uint64_t{0} - 15);
  expect_refused(encode({Command::pixels, p, pixels.bulk}), "more than 16 tiles");
  // The bounds the transport copies within: IMAGE 24 bytes a patch; PIXELS a static bound.
  EXPECT_EQ(message_bound(static_cast<uint8_t>(Command::image), 1000, 4).frames, 4u);
  EXPECT_GE(message_bound(static_cast<uint8_t>(Command::image), 1000, 4).bytes, 24000u);
  EXPECT_LT(message_bound(static_cast<uint8_t>(Command::image), 1000, 4).bytes, 24000u + 70000u);
  EXPECT_EQ(message_bound(static_cast<uint8_t>(Command::pixels), 0, 0).frames, 3 + kMaxTilesPerGrant);
  EXPECT_GE(message_bound(static_cast<uint8_t>(Command::pixels), 0, 0).bytes, kMaxTilesPerGrant * 64 * 64 * kPixelBytes);
}

// The same frames across a real ROUTER/DEALER pair: the ROUTER sees the routing id first, then
// the message; a malformed message is refused and the next good one still decodes.
// A string field with invalid UTF-8 is refused, and quietly: protobuf would log every such
// refusal to stderr, which a hostile peer could use to flood the log (proto/codec.cpp).
TEST(ProtoCodec, InvalidUtf8IsRefusedWithoutLogging) {
  std::vector<std::string> frames = encode(one_of_each()[0]);  // HELLO from "box-1"
  std::size_t at = frames[2].find("box-1");
  ASSERT_NE(at, std::string::npos);
  frames[2][at + 2] = '\xff';
  testing::internal::CaptureStderr();
  EXPECT_THROW(decode(frames), ProtocolError);
  std::string logged = testing::internal::GetCapturedStderr();
  EXPECT_EQ(logged, "");
}

TEST(ProtoCodec, FramesCrossARouterDealerPair) {
  zmq::context_t ctx;
  zmq::socket_t router(ctx, zmq::socket_type::router), dealer(ctx, zmq::socket_type::dealer);
  router.bind("tcp://127.0.0.1:*");
  std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  dealer.set(zmq::sockopt::routing_id, "node-0123456789abcdef");
  dealer.connect(endpoint);
  auto send = [&](const std::vector<std::string>& frames) {
    for (std::size_t i = 0; i < frames.size(); ++i)
      dealer.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
  };
  auto receive = [&] {
    std::vector<std::string> frames;
    zmq::message_t part;
    do {
      EXPECT_TRUE(router.recv(part));
      frames.emplace_back(part.to_string());
    } while (part.more());
    return frames;
  };
  auto messages = one_of_each();
  send({"HTTP/1.1", "GET"});
  send(encode(messages[5]));
  auto bad = receive();
  EXPECT_EQ(bad[0], "node-0123456789abcdef");
  EXPECT_THROW(decode({bad.begin() + 1, bad.end()}), ProtocolError);
  auto good = receive();
  Message m = decode({good.begin() + 1, good.end()});
  EXPECT_EQ(m.command, Command::report);
  EXPECT_EQ(m.bulk, messages[5].bulk);
}

}  // namespace
}  // namespace sirad::proto

namespace sirad::proto {
namespace {

// A received message is copied only within its command's bound (message_bound) for the
// receiver's run: a REPORT of 40 chunk frames to a run of 2 chunks is marked over with no more
// than 3 + 2 frames copied, its size counted whole; one within the bound arrives whole, and a
// signature frame larger than any signature is over before the command is known.
TEST(ProtoTransport, ReceiveCopiesOnlyWithinTheBound) {
  zmq::context_t ctx;
  zmq::socket_t a(ctx, zmq::socket_type::pair), b(ctx, zmq::socket_type::pair);
  a.bind("inproc://bound");
  b.connect("inproc://bound");
  const std::string chunk(24 * 5, '\0');  // a chunk of 5 patches
  std::vector<std::string> many = {std::string(kSignature), std::string(1, char(Command::report)), ""};
  for (int i = 0; i < 40; ++i) many.push_back(chunk);
  ASSERT_TRUE(send_frames(a, many));
  auto r = receive(b, 1000, 0, 10, 2);
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->over);
  EXPECT_LE(r->frames.size(), 5u);
  EXPECT_EQ(r->frames_seen, 43u);
  std::vector<std::string> fits(many.begin(), many.begin() + 5);
  ASSERT_TRUE(send_frames(a, fits));
  r = receive(b, 1000, 0, 10, 2);
  ASSERT_TRUE(r);
  EXPECT_FALSE(r->over);
  EXPECT_EQ(r->frames, fits);
  ASSERT_TRUE(send_frames(a, {std::string(1 << 20, 'S'), std::string(1, char(Command::heartbeat)), ""}));
  r = receive(b, 1000, 0, 10, 2);
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->over);
  EXPECT_TRUE(r->frames.empty());
}

// PeerBytes over real loopback TCP, a bound of 1 MiB: honest traffic (200 messages of 64 KiB,
// 12.5 MiB in all, each read and told to delivered()) is never shut, however much of it passes,
// since what was read is subtracted; one message of 64 frames of 256 KiB (16 MiB, each frame
// within ZMQ_MAXMSGSIZE) is shut while it arrives: never read, on_shut names the connection's
// address and more than the bound held, and the honest connection goes on. The watcher runs
// every 10 ms: the test waits for its events (the message read, the shut), bounded only by the
// suite's hang cap.
TEST(ProtoTransport, PeerBytesShutsAPeerWhoseUnreadBytesPassTheBound) {
  zmq::context_t ctx;
  zmq::socket_t router(ctx, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  harden(router, 1 << 20);
  std::mutex mutex;
  std::vector<std::pair<std::string, uint64_t>> shut;
  PeerBytes bytes(ctx, router, uint64_t{1} << 20, [&](const std::string& address, uint64_t held) {
    std::lock_guard lock(mutex);
    shut.emplace_back(address, held);
  });
  router.bind("tcp://127.0.0.1:*");
  const std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  zmq::socket_t honest(ctx, zmq::socket_type::dealer), flood(ctx, zmq::socket_type::dealer);
  for (zmq::socket_t* s : {&honest, &flood}) {
    s->set(zmq::sockopt::linger, 0);
    s->set(zmq::sockopt::sndhwm, 0);
    s->connect(endpoint);
  }
  const auto until = [](const std::function<bool()>& done) {  // within the suite's hang cap
    for (int i = 0; i < 90000; ++i, std::this_thread::sleep_for(std::chrono::milliseconds(10)))
      if (done()) return true;
    return false;
  };
  const std::string piece(64 << 10, 'h');
  for (int m = 0; m < 200; ++m) {
    ASSERT_TRUE(send_frames(honest, {piece}));
    std::optional<Received> r;
    ASSERT_TRUE(until([&] { return (r = receive(router, 0, 1, 0, 0)).has_value(); }));
    EXPECT_GE(r->fd, 0);
    bytes.delivered(r->fd, r->frames_seen, r->bytes_seen);
  }
  EXPECT_EQ(bytes.shut(), 0u);
  std::vector<std::string> big(64, std::string(256 << 10, 'f'));
  ASSERT_TRUE(send_frames(flood, big));
  ASSERT_TRUE(until([&] { return bytes.shut() == 1; }));
  {
    std::lock_guard lock(mutex);
    ASSERT_EQ(shut.size(), 1u);
    EXPECT_EQ(shut[0].first.rfind("127.0.0.1:", 0), 0u) << shut[0].first;
    EXPECT_GT(shut[0].second, uint64_t{1} << 20);
  }
  const std::vector<std::string> heartbeat = {std::string(kSignature), std::string(1, char(Command::heartbeat)), ""};
  ASSERT_TRUE(send_frames(honest, heartbeat));
  std::optional<Received> r;
  ASSERT_TRUE(until([&] { return (r = receive(router, 0, 1, 0, 0)).has_value(); }));
  ASSERT_FALSE(r->over);
  // The routing id, then the honest message: the flood's never came.
  EXPECT_EQ(std::vector<std::string>(r->frames.begin() + 1, r->frames.end()), heartbeat);
  EXPECT_EQ(bytes.shut(), 1u);
}

}  // namespace
}  // namespace sirad::proto
