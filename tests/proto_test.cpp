// sirad tests: the SIRAD/1 codec against proto/PROTOCOL.md: every message type round-trips;
// truncated, oversized, wrong-version, wrong-type and inconsistent messages are refused with a
// one-line reason. Then the same frames over a real ZeroMQ ROUTER/DEALER pair.
#include <cstring>

#include <gtest/gtest.h>
#include <zmq.hpp>

#include "proto/codec.h"

namespace sirad::proto {
namespace {

std::string doubles(std::initializer_list<double> v) {
  std::string s(v.size() * sizeof(double), '\0');
  std::memcpy(s.data(), std::data(v), s.size());
  return s;
}

std::vector<Message> one_of_each() {
  std::vector<Message> out;
  wire::Hello hello;
  hello.set_node_name("box-1");
  hello.set_sirad_version("0.1.0");
  hello.mutable_device()->set_name("pthread");
  hello.mutable_device()->set_compute_units(2);
  hello.add_scene_hashes("a228efa82102b19382e261846de1b214");
  out.push_back({Command::hello, hello, {}});
  wire::Welcome welcome;
  welcome.set_node_index(3);
  welcome.set_heartbeat_ms(1000);
  welcome.mutable_run()->set_seed(42);
  welcome.mutable_run()->add_chunk_starts(0);
  welcome.mutable_run()->add_chunk_starts(100);
  welcome.mutable_run()->set_topology("ring");
  out.push_back({Command::welcome, welcome, {}});
  wire::SceneChunk scene;
  scene.set_scene_hash("ab");
  scene.set_total_bytes(10);
  scene.set_offset(4);
  scene.set_last(true);
  out.push_back({Command::scene, scene, {std::string("sixbyt")}});
  wire::Ready ready;
  ready.set_ms_per_bundle(12.5);
  out.push_back({Command::ready, ready, {}});
  wire::Grant grant;
  grant.set_grant_id(7);
  auto* r = grant.add_ranges();
  r->set_first(100);
  r->set_last(164);
  grant.set_report_after(16);
  grant.add_report_chunks(1);
  out.push_back({Command::grant, grant, {}});
  wire::Report report;
  report.set_grant_id(7);
  report.add_chunks(1);
  report.add_counts(16);
  report.add_chunks(0);
  report.add_counts(16);
  out.push_back({Command::report, report, {doubles({1, 2, 3}), doubles({4, 5, 6, 7, 8, 9})}});
  out.push_back({Command::final_state, report, {doubles({1, 2, 3}), doubles({4, 5, 6})}});
  wire::Update update;
  update.set_exchange(2);
  update.add_chunks(5);
  update.add_counts(48);
  out.push_back({Command::update, update, {doubles({0.5, 0.25, 0.125})}});
  wire::Stop stop;
  stop.set_abandon_current(true);
  out.push_back({Command::stop, stop, {}});
  wire::Error error;
  error.set_reason("version mismatch");
  out.push_back({Command::error, error, {}});
  out.push_back({Command::heartbeat, std::monostate{}, {}});
  out.push_back({Command::bye, std::monostate{}, {}});
  return out;
}

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

// The same frames across a real ROUTER/DEALER pair: the ROUTER sees the routing id first, then
// the message; a malformed message is refused and the next good one still decodes.
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
