// sirad tests: the coordinator and nodes over real ZeroMQ sockets (inproc and loopback TCP), the
// same code as the embedded default: every bundle once, the furnace unbiased, the exchange
// policy followed (period I, fraction S, star and ring, sync and async).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <thread>

#include <unistd.h>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "coordinator/coordinator.h"
#include "node/node.h"
#include "proto/security.h"
#include "proto/transport.h"
#include "solver/metrics.h"
#include "tests/cluster_util.h"
#include "tests/process_util.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

using test::furnace;
using test::Outcome;
using test::run_cluster;

// The next message on a raw peer's socket, or none after the hang bound (tests/process_util.h
// kHangS). With `heartbeat` it says HEARTBEAT every 100 ms while it waits, as a node does: a
// peer that waits silently for a grant (which waits for the other nodes' set-up) is declared
// dead by the coordinator's liveness on a loaded machine, and with min_nodes 2 the run then
// never starts.
std::optional<proto::Message> next_message(zmq::socket_t& s, bool heartbeat) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(sirad::test::kHangS);
  while (std::chrono::steady_clock::now() < until) {
    if (auto f = proto::receive(s, 100)) return proto::decode(*f);
    if (heartbeat) proto::send(s, {proto::Command::heartbeat, {}, {}});
  }
  return std::nullopt;
}

// The status JSON escapes what a node may call itself.
TEST(Cluster, StatusJsonEscapesNodeNames) {
  Status s;
  s.bundles_done = 3;
  s.bundles = 10;
  s.patches = 1000;
  s.elapsed_s = 1.5;
  s.scenes_sent = 2;
  s.scenes_from_cache = 1;
  Status::Node n;
  n.name = "a\"b\\c\nd";
  n.bundles = 3;
  n.exchanges = 1;
  n.last_seen_s = 0.25;
  s.nodes.push_back(n);
  s.settings = {{"bundles", "10"}, {"exchange-every", "end"}};
  EXPECT_EQ(to_json(s),
            "{\"bundles_done\":3,\"bundles\":10,\"patches\":1000,\"elapsed_s\":1.5,\"bundles_per_s\":2.0,"
            "\"patch_bundles_per_s\":2000.0,\"error_estimate\":null,\"exchanges\":0,\"bytes_in\":0,\"bytes_out\":0,"
            "\"scenes_sent\":2,\"scenes_from_cache\":1,\"exchange_every\":0,\"exchange_fraction\":1.0,"
            "\"mode\":\"\",\"topology\":\"\",\"target_error\":null,\"ended_by\":null,"
            "\"settings\":{\"bundles\":\"10\",\"exchange-every\":\"end\"},\"nodes\":[{\"name\":\"a\\\"b\\\\c\\nd\","
            "\"device\":\"\",\"state\":\"\",\"bundles\":3,\"exchanges\":1,\"last_seen_s\":0.25,"
            "\"bundles_per_s\":0.0,\"busy_s\":0.0,\"idle_s\":0.0,\"bytes_in\":0,\"bytes_out\":0,\"suspicion\":0.0}]}\n");
  // It reads back (sirad model --from-run), the escaped name included.
  auto path = std::filesystem::temp_directory_path() / ("sirad_status_" + std::to_string(::getpid()) + ".json");
  s.exchange_every = 8;
  s.exchange_fraction = 0.25;
  s.mode = "sync";
  s.nodes[0].busy_s = 1.25;
  write_status(path.string(), s);
  Status back = read_status(path.string());
  std::filesystem::remove(path);
  ASSERT_EQ(back.nodes.size(), 1u);
  EXPECT_EQ(back.nodes[0].name, n.name);
  EXPECT_EQ(back.nodes[0].bundles, 3u);
  EXPECT_EQ(back.scenes_sent, 2u);
  EXPECT_EQ(back.error_estimate, -1.0);
  EXPECT_DOUBLE_EQ(back.nodes[0].busy_s, 1.25);
  EXPECT_EQ(back.exchange_every, 8u);
  EXPECT_DOUBLE_EQ(back.exchange_fraction, 0.25);
  EXPECT_EQ(back.mode, "sync");
  EXPECT_EQ(back.patches, 1000u);
  EXPECT_EQ(back.scenes_sent, 2u);
  EXPECT_EQ(back.scenes_from_cache, 1u);
}

// Three nodes over loopback TCP (a port the system picks): the bundles add up to the budget
// (the ledger refuses any index done twice), and the furnace's mean is 2 within 4 standard
// deviations of a 1024-bundle chain average (0.04; see SolverFurnace in solver_test.cpp).
TEST(Cluster, ThreeNodesOverTcpRunEveryBundleOnceAndStayUnbiased) {
  RunConfig c = furnace(1024);
  c.exchange_every = 32;
  Outcome o = run_cluster(c, 3, "tcp://127.0.0.1:*");
  uint64_t total = 0;
  for (const auto& n : o.result.nodes) {
    EXPECT_GT(n.bundles, 0u) << n.name;
    total += n.bundles;
  }
  EXPECT_EQ(total, 1024u);
  double mean = area_mean(o.mesh, o.result.radiosity);
  std::printf("3 nodes over TCP, furnace: mean %.5f\n", mean);
  EXPECT_NEAR(mean, 2.0, 0.04);
}

// The nodes' bundle counts add up to `total`, and every range a node ran starts at a multiple
// of `unit` (grants are whole units, so ranges start at multiples of it), except in the end of
// the budget where grants shrink below a unit (guided self-scheduling, Policy::grant_size):
// that starts once fewer than 2 unit / share bundles are left, share a node's part of the
// nodes' speed; 8 unit P leaves room for one node measured 4x slower than the others.
void expect_whole_grants(const Outcome& o, uint64_t unit, uint64_t total) {
  uint64_t sum = 0;
  for (const auto& n : o.result.nodes) sum += n.bundles;
  EXPECT_EQ(sum, total);
  const uint64_t tail = 8 * unit * o.result.nodes.size();
  int aligned = 0;
  for (const LedgerEntry& e : o.result.ledger) {
    if (e.range.first + tail >= total) continue;
    EXPECT_EQ(e.range.first % unit, 0u) << e.name << " [" << e.range.first << ", " << e.range.last << ")";
    ++aligned;
  }
  EXPECT_GT(aligned, 0);
}

// Stratified directions over 3 nodes (engine/bundle.h): the Run message carries them, the furnace
// stays unbiased (same bound as above: stratification lowers the noise, see directions_test),
// and grants are whole multiples of the interleave G = 10 (rho = 0.5): I = 32 becomes 40, so
// every range a node ran starts at a multiple of 10 but in the end of the budget.
TEST(Cluster, StratifiedDirectionsReachTheNodesAndGrantsAreWholeInterleaves) {
  RunConfig c = furnace(1024);
  c.exchange_every = 32;
  c.directions = Directions::stratified;
  Outcome o = run_cluster(c, 3, "inproc://stratified");
  expect_whole_grants(o, 10, 1024);
  double mean = area_mean(o.mesh, o.result.radiosity);
  std::printf("3 nodes, stratified directions, furnace: mean %.5f\n", mean);
  EXPECT_NEAR(mean, 2.0, 0.04);
  auto attrs = run_attributes(c, outcome_of(o.result), o.mesh, "furnace", true);
  bool found = false;
  for (const auto& [k, v] : attrs)
    if (k == "sirad.directions") found = std::get<std::string>(v) == "stratified";
  EXPECT_TRUE(found);
  c.rule = UpdateRule::average;
  EXPECT_THROW(run_cluster(c, 1, "inproc://stratified-average"), Error);
}

// With X = 1/4 shots per bundle, steps 4s .. 4s + 3 share shot s: grants are whole multiples of
// 4 (I = 30 becomes 32), so no shot is split between two nodes: every range a node ran starts
// at a multiple of 32 but in the end of the budget (grants of 30 would start at 30, 60, ...).
TEST(Cluster, GrantsKeepEachShotOnOneNode) {
  RunConfig c = furnace(1026);
  c.exchange_every = 30;
  c.shots_per_bundle = 0.25;
  c.balance = false;  // grants of exactly 32: a loaded machine can make one node look 2x slower (16)
  Outcome o = run_cluster(c, 3, "inproc://shot-grants");
  expect_whole_grants(o, 32, 1026);
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.04);
}

// Sync mode follows the period: with I = 16 and K = 256 over 2 nodes each node exchanges
// K / (2 I) = 8 times; S = 1/4 of 8 chunks sends 2 chunks per exchange, so the coordinator
// receives exactly 8 * 2 * 2 chunk states.
TEST(Cluster, SyncFollowsThePeriodAndFractionSelectsChunks) {
  RunConfig c = furnace(256);
  c.exchange_every = 16;
  c.fraction = 0.25;
  c.chunks = 8;
  c.mode = Mode::sync;
  c.balance = false;  // grants of exactly I bundles: a loaded machine can make one node look 2x slower
  Outcome o = run_cluster(c, 2, "inproc://cluster-sync");
  ASSERT_EQ(o.result.nodes.size(), 2u);
  for (const auto& n : o.result.nodes) {
    EXPECT_EQ(n.bundles, 128u) << n.name;  // the barrier shares the budget evenly
    EXPECT_EQ(n.exchanges, 8u) << n.name;
  }
  EXPECT_EQ(o.result.exchanges, 16u);
  // Traffic: every report sends the chunks of its rotation (3 doubles per patch), every update
  // answers with the same chunks, and each node's final state carries all patches.
  auto size = [&](uint32_t c) { return o.mesh.size() * (c + 1) / 8 - o.mesh.size() * c / 8; };
  uint64_t reports = 0;
  for (uint32_t e = 0; e < 8; ++e)
    for (uint32_t ch : exchange_chunks(e, 0.25, 8)) reports += 2 * 24 * size(ch);
  EXPECT_EQ(o.result.exchange_bytes_out, reports);
  EXPECT_EQ(o.result.exchange_bytes_in, reports);
  EXPECT_EQ(o.result.final_bytes, 2 * 24 * o.mesh.size());
}

// Ring forwards only the neighbour's state, star the sum of all others: both run the whole
// budget and keep the furnace unbiased (8 sigma of a 192-bundle chain average, ~0.02 each).
TEST(Cluster, RingAndStarBothRun) {
  for (Topology t : {Topology::ring, Topology::star}) {
    RunConfig c = furnace(192);
    c.exchange_every = 8;
    c.topology = t;
    Outcome o = run_cluster(c, 3, t == Topology::ring ? "inproc://cluster-ring" : "inproc://cluster-star");
    uint64_t total = 0;
    for (const auto& n : o.result.nodes) total += n.bundles;
    EXPECT_EQ(total, 192u);
    EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.08);
  }
}

// Hostile traffic during a real run: a raw ZeroMQ client sends a truncated message, a wrong
// version, an unknown command, a header that does not parse, a REPORT before HELLO, then
// (known now) a REPORT for a grant it never held, bulk frames missing, extra or not whole
// doubles, a header over 64 KiB, READY for another run, FINAL without STOP and a command only a
// coordinator sends. Each is refused (the frames by the decoder, which logs them; the rest
// answered with ERROR, the one before HELLO asking it to say HELLO) and the run completes with
// every bundle, unbiased.
TEST(Cluster, MalformedMessagesAreRefusedWhileARunGoesOn) {
  RunConfig c = furnace(256);
  c.exchange_every = 16;
  Outcome out;
  out.mesh = mesh_scene(c.scene, c.mesh_options);
  zmq::context_t context;
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  router.bind("tcp://127.0.0.1:*");
  std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  std::atomic<bool> stop{false};
  std::thread node([&] { node::serve(context, endpoint, {.name = "honest", .stop = &stop}); });
  std::thread attacker([&] {
    zmq::socket_t s(context, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.connect(endpoint);
    auto raw = [&](std::vector<std::string> frames) {
      for (std::size_t i = 0; i < frames.size(); ++i)
        s.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
    };
    wire::Report r;
    r.set_run_id(1);
    r.set_grant_id(1);
    auto* d = r.add_done();
    d->set_first(0);
    d->set_last(100);
    raw({"SIRAD1"});                                        // truncated
    raw({"SIRAD0", std::string(1, '\x01'), ""});          // wrong version
    raw({"SIRAD1", std::string(1, '\x42'), ""});          // unknown command
    raw({"SIRAD1", std::string(1, '\x06'), "\xff\xff"}); // header does not parse
    proto::send(s, {proto::Command::report, r, {}});        // REPORT before HELLO
    wire::Hello h;
    h.set_node_name("attacker");
    proto::send(s, {proto::Command::hello, h, {}});
    proto::send(s, {proto::Command::report, r, {}});        // a grant it never held
    wire::Report chunks = r;
    chunks.add_chunks(0);
    chunks.add_chunks(1);
    chunks.add_counts(1);
    chunks.add_counts(1);
    const std::string header = [&] { std::string h; chunks.SerializeToString(&h); return h; }();
    raw({"SIRAD1", std::string(1, '\x06'), header, std::string(24, '\0')});                           // a bulk frame missing
    raw({"SIRAD1", std::string(1, '\x06'), header, std::string(24, '\0'), std::string(24, '\0'),
         std::string(24, '\0')});                                                                      // one too many
    raw({"SIRAD1", std::string(1, '\x06'), header, std::string(24, '\0'), std::string(23, '\0')}); // not whole doubles
    raw({"SIRAD1", std::string(1, '\x0A'), std::string(70 * 1024, 'x')});                              // header over 64 KiB
    wire::Ready other;
    other.set_run_id(12345);
    proto::send(s, {proto::Command::ready, other, {}});     // READY for another run
    proto::send(s, {proto::Command::final_state, r, {}});   // FINAL without STOP
    wire::Grant g;
    proto::send(s, {proto::Command::grant, g, {}});         // a coordinator's command
    int errors = 0, rejoin = 0;
    for (int i = 0; i < 50 && errors < 5; ++i)
      if (auto f = proto::receive(s, 100)) {
        proto::Message m = proto::decode(*f);
        if (m.command != proto::Command::error) continue;
        ++errors;
        rejoin += std::get<wire::Error>(m.header).rejoin();
      }
    EXPECT_EQ(errors, 5) << "REPORT before HELLO, the foreign grant, READY for another run, FINAL without STOP and GRANT answer ERROR";
    EXPECT_EQ(rejoin, 1) << "only the REPORT before HELLO asks for a HELLO";
  });
  c.min_nodes = 1;
  c.timeout_s = 900;  // a hang guard (tests/process_util.h kHangS)
  out.result = coordinate(router, c, out.mesh);
  stop = true;
  node.join();
  attacker.join();
  uint64_t total = 0;
  for (const auto& n : out.result.nodes) total += n.bundles;
  EXPECT_EQ(total, 256u);
  EXPECT_NEAR(area_mean(out.mesh, out.result.radiosity), 2.0, 0.08);
}

// A frame larger than the run can legally carry (proto::max_frame_bytes: a chunk of every
// patch, or a SCENE frame, plus 64 KiB) never reaches the coordinator: ZeroMQ drops the
// sender's connection as soon as the frame's size arrives (ZMQ_MAXMSGSIZE), so a peer cannot
// make the coordinator allocate it. The attacker sees its connection close; the run completes.
TEST(Cluster, AnOversizeFrameDropsTheConnection) {
  RunConfig c = furnace(256);
  c.exchange_every = 16;
  c.timeout_s = 900;  // a hang guard (tests/process_util.h kHangS)
  Outcome out;
  out.mesh = mesh_scene(c.scene, c.mesh_options);
  zmq::context_t context;
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  proto::harden(router, proto::max_frame_bytes(out.mesh.size()));
  router.bind("tcp://127.0.0.1:*");
  std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  std::atomic<bool> stop{false};
  std::thread node([&] { node::serve(context, endpoint, {.name = "honest", .stop = &stop}); });
  bool dropped = false;
  std::thread attacker([&] {
    zmq::socket_t s(context, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    ASSERT_EQ(zmq_socket_monitor(s.handle(), "inproc://oversize-monitor", ZMQ_EVENT_DISCONNECTED), 0);
    zmq::socket_t monitor(context, zmq::socket_type::pair);
    monitor.connect("inproc://oversize-monitor");
    s.connect(endpoint);
    wire::Hello h;
    h.set_node_name("attacker");
    proto::send(s, {proto::Command::hello, h, {}});
    bool welcomed = false;
    for (int i = 0; i < 50 && !welcomed; ++i)
      if (auto f = proto::receive(s, 100)) welcomed = proto::decode(*f).command == proto::Command::welcome;
    ASSERT_TRUE(welcomed);
    wire::Report r;
    r.set_run_id(1);
    r.add_chunks(0);
    r.add_counts(1);
    proto::send(s, {proto::Command::report, r, {std::string(proto::max_frame_bytes(out.mesh.size()) + 8, '\0')}});
    dropped = proto::receive(monitor, 5000).has_value();
  });
  out.result = coordinate(router, c, out.mesh);
  stop = true;
  node.join();
  attacker.join();
  EXPECT_TRUE(dropped) << "the coordinator kept the connection of a peer sending an oversize frame";
  EXPECT_EQ(out.result.bundles, 256u);
}

// CURVE over TCP (proto/security.h): the coordinator admits only the node keys of its allow
// list. An allowed node runs the whole budget; a node with a key not on the list is refused at
// the handshake (the ZAP handler counts it) and a node holding an allowed key but trusting the
// wrong server key never completes its handshake: neither appears in the run or its result.
TEST(Cluster, OnlyNodesWithAnAllowedKeyTakePartOverCurve) {
  RunConfig c = furnace(256);
  c.exchange_every = 16;
  c.timeout_s = 900;  // a hang guard (tests/process_util.h kHangS)
  Outcome out;
  out.mesh = mesh_scene(c.scene, c.mesh_options);
  proto::KeyPair server = proto::generate_keypair(), allowed = proto::generate_keypair(),
                 stranger = proto::generate_keypair(), impostor_server = proto::generate_keypair();
  zmq::context_t context;
  auto zap = std::make_unique<proto::ZapHandler>(context, proto::AllowList{{allowed.public_key, "allowed"}});
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  proto::make_curve_server(router, server);
  router.bind("tcp://127.0.0.1:*");
  std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  std::atomic<bool> stop{false};
  std::vector<std::thread> nodes;
  auto start = [&](const char* name, const proto::KeyPair& keys, const std::string& server_key) {
    nodes.emplace_back([&, name, keys, server_key] {
      node::serve(context, endpoint, {.name = name, .stop = &stop, .curve_keys = keys, .server_key = server_key});
    });
  };
  start("allowed", allowed, server.public_key);
  start("stranger", stranger, server.public_key);
  start("fooled", allowed, impostor_server.public_key);
  out.result = coordinate(router, c, out.mesh);
  stop = true;
  for (auto& t : nodes) t.join();
  ASSERT_EQ(out.result.nodes.size(), 1u);
  EXPECT_EQ(out.result.nodes[0].name, "allowed");
  EXPECT_EQ(out.result.nodes[0].bundles, 256u);
  EXPECT_GE(zap->refused(), 1u) << "the stranger's handshake reached the ZAP handler and was refused";
  EXPECT_NEAR(area_mean(out.mesh, out.result.radiosity), 2.0, 0.0097 * std::sqrt(1024.0 / 256) * 4);
}

// A node with no run says HELLO with a back-off while no coordinator answers: here from 50 ms
// doubling to 400 ms (the defaults are 1 s to 32 s). A silent ROUTER records when each HELLO
// arrives: the gaps grow 50, 100, 200, 400, 400 ms (lower bounds: a loaded machine only
// stretches them). Once it answers (a WELCOME without a run), the back-off starts over: the next
// two HELLOs come 50 to 100 ms apart, not the 400 ms it had reached.
TEST(Cluster, NodeSaysHelloWithBackOffUntilACoordinatorAnswers) {
  zmq::context_t context;
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  router.bind("inproc://hello-backoff");
  std::atomic<bool> stop{false};
  std::thread node([&] {
    node::serve(context, "inproc://hello-backoff",
                {.name = "patient", .stop = &stop, .reconnect_ms = 50, .reconnect_max_ms = 400});
  });
  using Clock = std::chrono::steady_clock;
  auto next_hello = [&](std::string* id) -> Clock::time_point {
    for (int i = 0; i < 100; ++i)
      if (auto f = proto::receive(router, 50)) {
        *id = f->front();
        if (proto::decode({f->begin() + 1, f->end()}).command == proto::Command::hello) return Clock::now();
      }
    ADD_FAILURE() << "no HELLO within 5 s";
    return Clock::now();
  };
  std::string id;
  std::vector<Clock::time_point> at{next_hello(&id)};  // the first, at start
  for (int i = 0; i < 5; ++i) at.push_back(next_hello(&id));
  const double expected[] = {50, 100, 200, 400, 400};
  for (int i = 0; i < 5; ++i) {
    double gap = std::chrono::duration<double, std::milli>(at[i + 1] - at[i]).count();
    EXPECT_GT(gap, 0.8 * expected[i]) << "gap " << i;
  }
  wire::Welcome w;  // no run: "no run in progress"
  w.set_heartbeat_ms(1000);
  proto::send(router, {proto::Command::welcome, w, {}}, &id);
  auto first = next_hello(&id), second = next_hello(&id);
  double gap = std::chrono::duration<double, std::milli>(second - first).count();
  EXPECT_LT(gap, 300) << "the back-off starts over once a coordinator answers (it was at 400 ms)";
  stop = true;
  node.join();
}

// Under CURVE a quarantine sticks to the key: a liar with an allowed key sends NaN, is
// quarantined, and comes back on a new socket (a new routing id) with the same key: its HELLO
// is refused. Another allowed key is still welcome. The honest node finishes the run.
TEST(Cluster, AQuarantineSticksToTheCurveKey) {
  RunConfig c = furnace(2048);
  c.exchange_every = 16;
  c.timeout_s = 900;  // a hang guard (tests/process_util.h kHangS)
  c.min_nodes = 2;
  Outcome out;
  out.mesh = mesh_scene(c.scene, c.mesh_options);
  proto::KeyPair server = proto::generate_keypair(), honest = proto::generate_keypair(), liar = proto::generate_keypair(),
                 other = proto::generate_keypair();
  zmq::context_t context;
  proto::ZapHandler zap(context, {{honest.public_key, "honest"}, {liar.public_key, "liar"}, {other.public_key, "other"}});
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  proto::make_curve_server(router, server);
  router.bind("tcp://127.0.0.1:*");
  const std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  std::atomic<bool> stop{false};
  std::thread node([&] {
    node::serve(context, endpoint, {.name = "honest", .stop = &stop, .curve_keys = honest, .server_key = server.public_key});
  });
  auto dealer = [&](const proto::KeyPair& keys) {
    auto s = std::make_unique<zmq::socket_t>(context, zmq::socket_type::dealer);
    s->set(zmq::sockopt::linger, 0);
    proto::make_curve_client(*s, keys, server.public_key);
    s->connect(endpoint);
    return s;
  };
  auto hello = [&](zmq::socket_t& s, const char* name) {
    wire::Hello h;
    h.set_node_name(name);
    proto::send(s, {proto::Command::hello, h, {}});
  };
  // The first answer to a HELLO that is WELCOME or ERROR.
  auto answer = [&](zmq::socket_t& s) {
    while (std::optional<proto::Message> m = next_message(s, false))
      if (m->command == proto::Command::welcome || m->command == proto::Command::error) return *m;
    return proto::Message{};
  };
  bool refused = false, other_welcome = false;
  std::thread attacker([&] {
    auto s = dealer(liar);
    hello(*s, "liar");
    proto::Message w = answer(*s);
    ASSERT_EQ(w.command, proto::Command::welcome);
    wire::Run run = std::get<wire::Welcome>(w.header).run();
    wire::Ready ready;
    ready.set_run_id(run.run_id());
    proto::send(*s, {proto::Command::ready, ready, {}});
    while (std::optional<proto::Message> next = next_message(*s, true)) {
      proto::Message& m = *next;
      if (m.command != proto::Command::grant) continue;
      const auto& g = std::get<wire::Grant>(m.header);
      wire::Report r;
      r.set_run_id(run.run_id());
      r.set_grant_id(g.grant_id());
      *r.mutable_done() = g.ranges();
      r.add_chunks(0);
      r.add_counts(1);
      std::size_t n = run.chunk_starts_size() > 1 ? run.chunk_starts(1) : run.patches();
      proto::send(*s, {proto::Command::report, r, {proto::pack(std::vector<double>(3 * n, std::nan("")))}});
      break;
    }
    ASSERT_EQ(answer(*s).command, proto::Command::error);  // quarantined
    s.reset();
    auto again = dealer(liar);  // a new routing id, the same key
    hello(*again, "liar-again");
    refused = answer(*again).command == proto::Command::error;
    auto fresh = dealer(other);
    hello(*fresh, "other");
    other_welcome = answer(*fresh).command == proto::Command::welcome;
  });
  out.result = coordinate(router, c, out.mesh);
  stop = true;
  node.join();
  attacker.join();
  EXPECT_TRUE(refused) << "the quarantined key came back on a new socket";
  EXPECT_TRUE(other_welcome);
  EXPECT_FALSE(test::node_named(out.result, "liar").quarantined.empty());
  EXPECT_EQ(test::node_named(out.result, "honest").bundles, 2048u);
  for (const auto& n : out.result.nodes) EXPECT_NE(n.name, "liar-again");
}

// What a lying node sends after one plausible but far-off report.
enum class Lie { nan_sum, infinite_error_estimate, count_beyond_bundles };

struct LiarRun {
  Outcome out;
  Status last;             // the coordinator's last status
  int errors = 0;          // ERRORs the liar received
  bool hello_refused = false;  // its HELLO after the quarantine was answered with ERROR
};

// An honest node thread and a liar on a raw socket. The liar's first REPORT is accepted: every
// patch at 50 (the furnace's answer is 2) with a count of 16. Its second is the lie, which
// quarantines it: ERROR back, its data (the 50s too) dropped, its bundles returned to the
// budget. Then it says HELLO again, which is refused.
LiarRun run_with_liar(Lie lie) {
  RunConfig c = furnace(1024);
  c.exchange_every = 16;
  c.min_nodes = 2;
  c.timeout_s = 900;  // a hang guard (tests/process_util.h kHangS)
  c.status_every_s = 0.05;
  LiarRun run;
  c.status = [&](const Status& s) { run.last = s; };
  run.out.mesh = mesh_scene(c.scene, c.mesh_options);
  zmq::context_t context;
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  router.bind("inproc://cluster-liar");
  std::atomic<bool> stop{false};
  std::thread node([&] { node::serve(context, "inproc://cluster-liar", {.name = "honest", .stop = &stop}); });
  std::thread liar([&] {
    zmq::socket_t s(context, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.connect("inproc://cluster-liar");
    wire::Hello h;
    h.set_node_name("liar");
    proto::send(s, {proto::Command::hello, h, {}});
    wire::Run run_settings;
    int reports = 0;
    uint64_t bundles = 0;
    while (reports < 2) {
      std::optional<proto::Message> next = next_message(s, true);
      if (!next) break;
      proto::Message& m = *next;
      if (m.command == proto::Command::welcome) {
        run_settings = std::get<wire::Welcome>(m.header).run();
        wire::Ready r;
        r.set_run_id(run_settings.run_id());
        proto::send(s, {proto::Command::ready, r, {}});
      } else if (m.command == proto::Command::grant) {
        const auto& g = std::get<wire::Grant>(m.header);
        for (const auto& range : g.ranges()) bundles += range.last() - range.first();
        wire::Report r;
        r.set_run_id(run_settings.run_id());
        r.set_grant_id(g.grant_id());
        *r.mutable_done() = g.ranges();
        r.set_error_estimate(reports == 1 && lie == Lie::infinite_error_estimate ? std::numeric_limits<double>::infinity() : 0.01);
        r.add_chunks(0);
        r.add_counts(reports == 1 && lie == Lie::count_beyond_bundles ? 1000 * bundles : bundles);
        std::size_t n = run_settings.chunk_starts_size() > 1 ? run_settings.chunk_starts(1) : run_settings.patches();
        std::vector<double> sum(3 * n, 50.0 * static_cast<double>(bundles));
        if (reports == 1 && lie == Lie::nan_sum) sum[1] = std::nan("");
        proto::send(s, {proto::Command::report, r, {proto::pack(sum)}});
        ++reports;
      } else if (m.command == proto::Command::error) {
        ++run.errors;
      }
    }
    while (run.errors == 0)  // the ERROR for the lie (quarantined: no heartbeats now)
      if (auto m = next_message(s, false)) run.errors += m->command == proto::Command::error;
      else break;
    proto::send(s, {proto::Command::hello, h, {}});
    while (!run.hello_refused)
      if (auto m = next_message(s, false)) run.hello_refused = m->command == proto::Command::error;
      else break;
  });
  run.out.result = coordinate(router, c, run.out.mesh);
  stop = true;
  node.join();
  liar.join();
  return run;
}

// A node that sends NaN, an infinite error estimate or a count beyond the bundles it has run
// is quarantined and the result is unaffected: its accepted report (every patch at 50 over 16
// bundles) is dropped with it, so the furnace's mean stays 2 within 4 sigma of a 1024-bundle
// chain average (0.0097 x 4 = 0.039; kept, the 50s would shift it by 48 x 16 / 1040 = 0.74).
// Its bundles return to the budget: the honest node runs all 1024. The
// status shows it quarantined, with the reason; its HELLO afterwards is refused.
TEST(Cluster, ANodeSendingImpossibleValuesIsQuarantinedAndTheResultUnaffected) {
  for (Lie lie : {Lie::nan_sum, Lie::infinite_error_estimate, Lie::count_beyond_bundles}) {
    SCOPED_TRACE(static_cast<int>(lie));
    LiarRun run = run_with_liar(lie);
    const RunResult& r = run.out.result;
    EXPECT_EQ(r.bundles, 1024u);
    EXPECT_EQ(test::node_named(r, "honest").bundles, 1024u) << "the liar's bundles are run again";
    const NodeReport& liar = test::node_named(r, "liar");
    EXPECT_TRUE(liar.dead);
    EXPECT_EQ(liar.bundles, 0u);
    const char* reason = lie == Lie::nan_sum ? "nan" : lie == Lie::infinite_error_estimate ? "error estimate" : "exceeds";
    EXPECT_NE(liar.quarantined.find(reason), std::string::npos) << liar.quarantined;
    EXPECT_EQ(run.errors, 1) << "the lie answers ERROR; the report before it was accepted";
    EXPECT_TRUE(run.hello_refused);
    auto in_status = std::find_if(run.last.nodes.begin(), run.last.nodes.end(), [](const Status::Node& n) { return n.name == "liar"; });
    ASSERT_NE(in_status, run.last.nodes.end());
    EXPECT_EQ(in_status->state, "quarantined");
    EXPECT_NE(in_status->why.find(reason), std::string::npos);
    EXPECT_NEAR(area_mean(run.out.mesh, r.radiosity), 2.0, 0.0097 * 4);
  }
}

}  // namespace
}  // namespace sirad::cluster
