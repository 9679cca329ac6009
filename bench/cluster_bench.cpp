// sirad bench: the costs of the cluster, for the paper's model
//     T = N T_i + (N P S / I) T_e
// measured with the real code: the SIRAD/1 codec and transport, the coordinator's Aggregate,
// coordinate() and node::serve, the Solver on the OpenCL engine. Prints CSV on stdout; lines
// starting with '#' are comments (settings, expectations, checks).
//
// Columns: measure,transport,param,stat,value,unit
//   measure    exchange_ms        one exchange, node-side round trip: the node's REPORT of
//                                 `chunks` chunks (bulk double frames: pack, proto::send; the
//                                 coordinator's proto::receive, decode, unpack, Aggregate::set)
//                                 and the coordinator's UPDATE back (Aggregate::others (star, 2
//                                 nodes), pack, send; the node's receive, decode, unpack);
//                                 ROUTER and DEALER in one process, the node on its own thread.
//                                 param: patches=N;bytes=B (B = 24 N, bulk of one direction)
//              exchange_coord_ms  the coordinator's part of it (decode .. UPDATE sent)
//              exchange_faults    minor page faults of the process per exchange (getrusage)
//              exchange_ms_per_mb median exchange_ms / MB (10^6 bytes of one-way bulk) per size
//              exchange_fit       least-squares line through the medians of all sizes: stat
//                                 latency (intercept, ms), ms_per_mb (slope: ms per 10^6 bytes
//                                 of one-way bulk, the same again coming back); the largest size
//                                 dominates it
//              bundle_ms          T_i: Solver::step on the OpenCL engine, Cornell box, auto grid
//                                 (param patches=N;grid=R)
//              exchange_bytes     bytes per exchange from coordinate() runs over inproc (param
//                                 S=..;patches=..;nodes=..): stat report, update (measured),
//                                 expected (24 * patches of the chunks the rotation named),
//                                 nominal (24 * patches * n / C, n = ceil(S C)), exchanges
//              embedded_s         end to end, single node (transport single: mesh,
//                                 make_cl_engine, Solver with burn-in, K steps, estimate) and the
//                                 embedded default with one node (transport inproc: mesh,
//                                 coordinate() + one node::serve thread, which meshes again and
//                                 builds its engine, then stop, join, teardown); interleaved
//                                 A B A B; stat median, min, max, and coordinate_median (until
//                                 coordinate() returns) and join_median (stop + join + teardown:
//                                 up to one node poll interval, --node-poll-ms, 100 as in
//                                 the embedded driver)
//              embedded_ratio     stat median_ratio (median B / median A), paired_ratio (median
//                                 of B_i / A_i, with its quartiles), paired_diff (median of
//                                 B_i - A_i, s) and paired_diff_coordinate (the same, B until
//                                 coordinate() returns)
//              embedded_grants    embedded runs with grant size I and the smallest possible
//                                 exchange (one chunk of C = 4096, ~2 patches) per grant, and
//                                 the default (I=end: grants of K / 8, no exchange), interleaved:
//                                 param I=..;grants=..: median seconds until coordinate() returns
//                                 (--grant-reps runs each); stat per_grant_ms (slope of the fit)
//              component_ms       the parts the two paths differ in, timed alone: mesh (the
//                                 node's second meshing), scene_codec (encode_scene +
//                                 decode_scene), engine (make_cl_engine, paid by both), burn_in
//                                 (Solver construction, paid by both)
//
//   sirad_bench_cluster [--sections te,ti,bytes,embedded] [--sizes 0,1000,10000,100000,1000000]
//       [--exchange-reps 200] [--exchange-chunks 16] [--ti-patches 5000,10000,20000] [--ti-bundles 50]
//       [--patches 10000] [--bundles 1000] [--reps 15] [--grant-reps 3] [--seed 1] [--grid 0]
//       [--bytes-nodes 2] [--bytes-bundles 256] [--exchange-every 16] [--chunks 16]
//       [--grant-sizes 1,16,125|none] [--node-poll-ms 100] [--device D]
// The defaults take about 3.5 minutes on 2 CPU cores (PoCL). Quick smoke run (< 1 min):
//   --exchange-reps 20 --sizes 0,1000,100000 --ti-bundles 10 --bundles 100 --reps 2
//   --grant-reps 1 --bytes-bundles 64 --grant-sizes 1
// Run-to-run noise of several percent (a shared or virtual machine) swamps a 3 % overhead in a
// few repetitions: hence 15 interleaved pairs and the paired ratio.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <sys/resource.h>

#include <fmt/format.h>
#include <glm/vec3.hpp>
#include <zmq.hpp>

#include "cli/embedded.h"
#include "cluster/exchange.h"
#include "cluster/worker.h"
#include "engine/bundle_cl.h"
#include "proto/codec.h"
#include "proto/transport.h"
#include "scene/encoding.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/solver.h"
#include "solver/solver.h"
#include "util/error.h"

using namespace sirad;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double quantile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::lround(p * static_cast<double>(v.size() - 1)))];
}
double median(const std::vector<double>& v) { return quantile(v, 0.5); }

void row(const std::string& measure, const std::string& transport, const std::string& param, const std::string& stat,
         double value, const std::string& unit) {
  std::printf("%s,%s,%s,%s,%.6g,%s\n", measure.c_str(), transport.c_str(), param.c_str(), stat.c_str(), value, unit.c_str());
  std::fflush(stdout);
}

void spread_rows(const std::string& measure, const std::string& transport, const std::string& param,
                 const std::vector<double>& v, const std::string& unit) {
  row(measure, transport, param, "median", median(v), unit);
  row(measure, transport, param, "q1", quantile(v, 0.25), unit);
  row(measure, transport, param, "q3", quantile(v, 0.75), unit);
  row(measure, transport, param, "min", quantile(v, 0.0), unit);
  row(measure, transport, param, "max", quantile(v, 1.0), unit);
  row(measure, transport, param, "reps", static_cast<double>(v.size()), "count");
}

// Least-squares line y = a + b x.
std::pair<double, double> fit(const std::vector<double>& x, const std::vector<double>& y) {
  double n = static_cast<double>(x.size()), sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  double d = n * sxx - sx * sx;
  if (x.size() < 2 || d == 0) return {NAN, NAN};
  double b = (n * sxy - sx * sy) / d;
  return {(sy - b * sx) / n, b};
}

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(item);
  return out;
}

// ---- 1. T_e: one exchange through the real codec, ROUTER <-> DEALER -------------------------

struct ExchangeTimes {
  std::vector<double> round_ms, coord_ms;
  double faults = 0;  // minor page faults of the process per exchange (both threads)
};

long minor_faults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

ExchangeTimes time_exchange(zmq::context_t& context, const std::string& bind, uint32_t patches, uint32_t chunks,
                            int reps, int warmup) {
  zmq::socket_t router(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  router.bind(bind);
  const std::string endpoint = router.get(zmq::sockopt::last_endpoint);
  const uint32_t c = patches == 0 ? 0 : std::min(chunks, patches);
  std::vector<uint32_t> starts = patches == 0 ? std::vector<uint32_t>{0, 0} : cluster::chunk_starts(patches, c);
  const int total = warmup + reps;

  ExchangeTimes times;
  std::exception_ptr node_error;
  std::atomic<bool> node_failed{false};
  std::thread node([&] {
    try {
      zmq::socket_t dealer(context, zmq::socket_type::dealer);
      dealer.set(zmq::sockopt::linger, 0);
      dealer.connect(endpoint);
      // The node's running sums, as the Solver keeps them.
      std::vector<glm::dvec3> sum(patches, glm::dvec3(0.25, 0.5, 0.75));
      for (int rep = 0; rep < total; ++rep) {
        auto t0 = Clock::now();
        // REPORT: as node.cpp's chunk_frames, every chunk (S = 1).
        wire::Report report;
        report.set_run_id(1);
        report.set_grant_id(static_cast<uint64_t>(rep + 1));
        std::vector<std::string> bulk;
        for (uint32_t ch = 0; ch < c; ++ch) {
          std::vector<double> v = cluster::flatten(std::span<const glm::dvec3>(sum).subspan(starts[ch], starts[ch + 1] - starts[ch]));
          report.add_chunks(ch);
          report.add_counts(static_cast<uint64_t>(rep + 1));
          bulk.push_back(proto::pack(v));
        }
        proto::Message m{proto::Command::report, {}, std::move(bulk)};
        m.header = report;
        proto::send(dealer, m);
        // UPDATE: as node.cpp's update, up to the doubles as dvec3 (absorb is the Solver's).
        auto frames = proto::receive(dealer, 30000);
        if (!frames) fail("exchange bench: no UPDATE within 30 s");
        proto::Message u = proto::decode(*frames);
        const auto& header = std::get<wire::Update>(u.header);
        std::size_t got = 0;
        for (int i = 0; i < header.chunks_size(); ++i) {
          got += cluster::unflatten(proto::unpack(u.bulk[static_cast<std::size_t>(i)])).size();
        }
        if (got != patches) fail("exchange bench: UPDATE carried {} patches, expected {}", got, patches);
        if (rep >= warmup) times.round_ms.push_back(1e3 * seconds_since(t0));
      }
    } catch (...) {
      node_error = std::current_exception();
      node_failed = true;
    }
  });

  try {
    // The coordinator's side: two nodes in the aggregate, node 1's state set once (star: node 0
    // receives node 1's sums).
    std::unique_ptr<cluster::Aggregate> aggregate;
    if (c > 0) {
      aggregate = std::make_unique<cluster::Aggregate>(starts, 2);
      for (uint32_t ch = 0; ch < c; ++ch) aggregate->set(1, ch, std::vector<double>(3 * aggregate->chunk_size(ch), 0.5), 7);
    }
    long faults0 = 0;
    for (int rep = 0; rep < total; ++rep) {
      if (rep == warmup) faults0 = minor_faults();
      std::optional<std::vector<std::string>> frames;
      while (!frames && !node_failed) frames = proto::receive(router, 100);
      if (!frames) break;
      auto t0 = Clock::now();
      std::string id = frames->front();
      proto::Message m = proto::decode({frames->begin() + 1, frames->end()});
      const auto& r = std::get<wire::Report>(m.header);
      wire::Update u;
      u.set_run_id(1);
      u.set_exchange(static_cast<uint32_t>(rep));
      std::vector<std::string> out;
      for (int i = 0; i < r.chunks_size(); ++i)
        aggregate->set(0, r.chunks(i), proto::unpack(m.bulk[static_cast<std::size_t>(i)]), r.counts(i));
      for (uint32_t ch : r.chunks()) {
        cluster::Aggregate::Part part = aggregate->others(0, ch, cluster::Topology::star);
        u.add_chunks(ch);
        u.add_counts(part.count);
        out.push_back(proto::pack(part.sum));
      }
      proto::send(router, {proto::Command::update, u, std::move(out)}, &id);
      if (rep >= warmup) times.coord_ms.push_back(1e3 * seconds_since(t0));
    }
    times.faults = static_cast<double>(minor_faults() - faults0) / std::max(reps, 1);
  } catch (...) {
    node.join();
    throw;
  }
  node.join();
  if (node_error) std::rethrow_exception(node_error);
  return times;
}

void bench_exchange(const std::vector<uint32_t>& sizes, uint32_t chunks, int reps) {
  std::printf("# T_e: one exchange = REPORT of all %u chunks (S = 1) + UPDATE back, 24 bytes per patch each way;\n"
              "# node-side round trip; reps per size: min(%d, max(15, 2e9 / (48 * patches))), after 3 warm-up\n",
              chunks, reps);
  zmq::context_t context;
  int serial = 0;
  for (const char* transport : {"inproc", "tcp"}) {
    std::vector<double> mb, ms;
    for (uint32_t n : sizes) {
      int r = reps;
      if (n > 0) r = std::min<int>(reps, std::max<int>(15, static_cast<int>(2e9 / (48.0 * n))));
      std::string bind = std::string(transport) == "inproc" ? fmt::format("inproc://bench-exchange-{}", serial++)
                                                            : std::string("tcp://127.0.0.1:*");
      ExchangeTimes t = time_exchange(context, bind, n, chunks, r, 3);
      std::string param = fmt::format("patches={};bytes={}", n, 24ull * n);
      spread_rows("exchange_ms", transport, param, t.round_ms, "ms");
      row("exchange_coord_ms", transport, param, "median", median(t.coord_ms), "ms");
      row("exchange_faults", transport, param, "mean", t.faults, "faults");
      if (n > 0) row("exchange_ms_per_mb", transport, param, "median", median(t.round_ms) / (24.0 * n / 1e6), "ms/MB");
      mb.push_back(24.0 * n / 1e6);
      ms.push_back(median(t.round_ms));
    }
    auto [a, b] = fit(mb, ms);
    row("exchange_fit", transport, "all_sizes", "latency", a, "ms");
    row("exchange_fit", transport, "all_sizes", "ms_per_mb", b, "ms/MB");
  }
}

// ---- 2. T_i: ms per bundle of Solver::step ----------------------------------------------------

void bench_bundles(const Scene& scene, const std::vector<std::size_t>& patch_counts, int bundles, uint64_t seed,
                   int grid, const std::string& device) {
  for (std::size_t target : patch_counts) {
    PatchMesh mesh = mesh_scene(scene, {.target_patches = target});
    auto engine = make_cl_engine(mesh, {.device = device});
    Solver solver(mesh, *engine, {.seed = seed, .grid = grid});
    solver.step(0);  // warm-up
    std::vector<double> ms;
    for (int k = 1; k <= bundles; ++k) {
      auto t0 = Clock::now();
      solver.step(static_cast<uint64_t>(k));
      ms.push_back(1e3 * seconds_since(t0));
    }
    if (target == patch_counts.front()) std::printf("# T_i: device %s; Solver::step after one warm-up step\n", engine->description().c_str());
    spread_rows("bundle_ms", "opencl", fmt::format("patches={};grid={}", mesh.size(), solver.grid()), ms, "ms");
  }
}

// ---- cluster runs: coordinate() + node::serve threads over inproc -----------------------------

struct ClusterRun {
  cluster::RunResult result;
  double total_s = 0, coordinate_s = 0, join_s = 0;
};

// The embedded driver (cli/embedded.h), as `sirad render --nodes` runs it: the scene meshed
// here, then the coordinator on this thread and `nodes` node threads; timed from before the
// meshing to the end of the teardown.
int g_node_poll_ms = 100;  // NodeOptions::poll_ms of the node threads (100: as sirad render --nodes)

ClusterRun run_cluster(cluster::RunConfig rc, int nodes, const std::string& device, int serial) {
  ClusterRun out;
  auto t0 = Clock::now();
  PatchMesh mesh = mesh_scene(rc.scene, rc.mesh_options);
  const double mesh_s = seconds_since(t0);
  rc.min_nodes = static_cast<uint32_t>(nodes);
  rc.timeout_s = 600;
  embedded::Outcome o = embedded::run(rc, mesh, {.nodes = nodes, .endpoint = fmt::format("inproc://bench-cluster-{}", serial),
                                                 .device = device, .poll_ms = g_node_poll_ms});
  out.result = std::move(o.result);
  out.coordinate_s = mesh_s + o.coordinate_s;
  out.total_s = seconds_since(t0);
  out.join_s = out.total_s - out.coordinate_s;
  return out;
}

cluster::RunConfig base_config(const Scene& scene, std::size_t patches, uint64_t bundles, uint64_t seed, int grid) {
  cluster::RunConfig rc;
  rc.scene = scene;
  rc.mesh_options.target_patches = patches;
  rc.bundles = bundles;
  rc.seed = seed;
  rc.grid = grid;
  return rc;
}

// ---- 3. bytes per exchange --------------------------------------------------------------------

void bench_bytes(const Scene& scene, std::size_t patches, uint64_t bundles, int nodes, uint32_t every, uint32_t chunks,
                 uint64_t seed, int grid, const std::string& device, int& serial) {
  PatchMesh mesh = mesh_scene(scene, {.target_patches = patches});
  const uint32_t n = static_cast<uint32_t>(mesh.size());
  std::vector<uint32_t> starts = cluster::chunk_starts(n, std::min(chunks, n));
  const uint32_t c = static_cast<uint32_t>(starts.size() - 1);
  for (double fraction : {1.0, 0.125}) {
    cluster::RunConfig rc = base_config(scene, patches, bundles, seed, grid);
    rc.exchange_every = every;
    rc.fraction = fraction;
    rc.chunks = chunks;
    ClusterRun run = run_cluster(rc, nodes, device, serial++);
    const auto& r = run.result;
    // Expected: each node's e-th exchange names exchange_chunks(e, S, C), 24 bytes per patch of
    // those, REPORT and UPDATE alike; every node's FINAL (all patches) is RunResult::final_bytes.
    uint64_t expected = 0;
    for (const auto& node : r.nodes)
      for (uint32_t e = 0; e < node.exchanges; ++e)
        for (uint32_t ch : cluster::exchange_chunks(e, fraction, c)) expected += 24ull * (starts[ch + 1] - starts[ch]);
    uint32_t sent = static_cast<uint32_t>(cluster::exchange_chunks(0, fraction, c).size());
    double ex = std::max<uint32_t>(r.exchanges, 1);
    double report = static_cast<double>(r.exchange_bytes_in) / ex;  // FINALs are counted apart
    double update = static_cast<double>(r.exchange_bytes_out) / ex;
    std::string param = fmt::format("S={};patches={};nodes={};I={};C={}", fraction, n, nodes, every, c);
    std::printf("# bytes, S = %g: %u of %u chunks per exchange; expected REPORT = UPDATE = 24 * patches of those "
                "chunks (= 24 * %u * %u / %u = %.0f B on average); REPORT bytes exclude the %zu FINALs (24 * %u B each)\n",
                fraction, sent, c, n, sent, c, 24.0 * n * sent / c, r.nodes.size(), n);
    row("exchange_bytes", "inproc", param, "report", report, "B");
    row("exchange_bytes", "inproc", param, "update", update, "B");
    row("exchange_bytes", "inproc", param, "expected", static_cast<double>(expected) / ex, "B");
    row("exchange_bytes", "inproc", param, "nominal", 24.0 * n * sent / c, "B");
    row("exchange_bytes", "inproc", param, "exchanges", r.exchanges, "count");
    bool ok = r.exchange_bytes_out == expected && r.exchange_bytes_in == expected &&
              r.final_bytes == 24ull * n * r.nodes.size();
    std::printf("# check S = %g: measured %s expected (in %llu B, out %llu B over %u exchanges)\n", fraction,
                ok ? "equals" : "DIFFERS FROM", static_cast<unsigned long long>(r.exchange_bytes_in),
                static_cast<unsigned long long>(r.exchange_bytes_out), r.exchanges);
  }
}

// ---- 4. embedded overhead ---------------------------------------------------------------------

struct SingleRun {
  double total_s = 0;
  std::vector<glm::vec3> radiosity;
  uint64_t crossings = 0;
};

// The single-node path of `sirad render`: mesh, engine, Solver (burn-in), K steps, estimate.
SingleRun run_single(const Scene& scene, std::size_t patches, uint64_t bundles, uint64_t seed, int grid,
                     const std::string& device) {
  SingleRun out;
  auto t0 = Clock::now();
  PatchMesh mesh = mesh_scene(scene, {.target_patches = patches});
  auto engine = make_cl_engine(mesh, {.device = device});
  Solver solver(mesh, *engine, {.seed = seed, .grid = grid});
  uint64_t c0 = solver.crossings();
  for (uint64_t k = 0; k < bundles; ++k) solver.step(k);
  out.radiosity = solver.estimate();
  out.total_s = seconds_since(t0);
  out.crossings = solver.crossings() - c0;
  return out;
}

void bench_embedded(const Scene& scene, std::size_t patches, uint64_t bundles, int reps, int grant_reps, uint64_t seed, int grid,
                    const std::vector<uint32_t>& grant_sizes, const std::string& device, int& serial) {
  std::printf("# embedded: Cornell, target %zu patches, K = %llu, seed %llu, grid %d (0: auto), node poll %d ms, %d "
              "interleaved reps after one untimed warm-up of each\n",
              patches, static_cast<unsigned long long>(bundles), static_cast<unsigned long long>(seed), grid,
              g_node_poll_ms, reps);
  cluster::RunConfig rc = base_config(scene, patches, bundles, seed, grid);  // the defaults of `sirad render --nodes 1`
  run_single(scene, patches, bundles, seed, grid, device);
  run_cluster(rc, 1, device, serial++);
  std::vector<double> a, b, b_coord, b_join, ratio, diff, diff_coord;
  SingleRun last_a;
  ClusterRun last_b;
  for (int i = 0; i < reps; ++i) {
    last_a = run_single(scene, patches, bundles, seed, grid, device);
    last_b = run_cluster(rc, 1, device, serial++);
    a.push_back(last_a.total_s);
    b.push_back(last_b.total_s);
    b_coord.push_back(last_b.coordinate_s);
    b_join.push_back(last_b.join_s);
    ratio.push_back(last_b.total_s / last_a.total_s);
    diff.push_back(last_b.total_s - last_a.total_s);
    diff_coord.push_back(last_b.coordinate_s - last_a.total_s);
    std::printf("# rep %d: single %.3f s, embedded %.3f s (coordinate %.3f s, join %.3f s)\n", i + 1, last_a.total_s,
                last_b.total_s, last_b.coordinate_s, last_b.join_s);
  }
  // Same work: the same counted crossings, and the same estimate.
  float maxdiff = 0;
  for (std::size_t j = 0; j < last_a.radiosity.size() && j < last_b.result.radiosity.size(); ++j)
    for (int ch = 0; ch < 3; ++ch) maxdiff = std::max(maxdiff, std::abs(last_a.radiosity[j][ch] - last_b.result.radiosity[j][ch]));
  std::printf("# check: crossings single %llu, embedded %llu; largest radiosity difference %g; grid %d\n",
              static_cast<unsigned long long>(last_a.crossings), static_cast<unsigned long long>(last_b.result.crossings),
              maxdiff, last_b.result.grid);
  std::string param = fmt::format("patches={};K={};grid={}", last_a.radiosity.size(), bundles, last_b.result.grid);
  row("embedded_s", "single", param, "median", median(a), "s");
  row("embedded_s", "single", param, "min", quantile(a, 0), "s");
  row("embedded_s", "single", param, "max", quantile(a, 1), "s");
  row("embedded_s", "inproc", param, "median", median(b), "s");
  row("embedded_s", "inproc", param, "min", quantile(b, 0), "s");
  row("embedded_s", "inproc", param, "max", quantile(b, 1), "s");
  row("embedded_s", "inproc", param, "coordinate_median", median(b_coord), "s");
  row("embedded_s", "inproc", param, "join_median", median(b_join), "s");
  row("embedded_ratio", "inproc", param, "median_ratio", median(b) / median(a), "x");
  row("embedded_ratio", "inproc", param, "paired_ratio", median(ratio), "x");
  row("embedded_ratio", "inproc", param, "paired_ratio_q1", quantile(ratio, 0.25), "x");
  row("embedded_ratio", "inproc", param, "paired_ratio_q3", quantile(ratio, 0.75), "x");
  row("embedded_ratio", "inproc", param, "paired_diff", median(diff), "s");
  row("embedded_ratio", "inproc", param, "paired_diff_coordinate", median(diff_coord), "s");

  // Where it goes: the parts only the embedded path has, timed alone.
  std::vector<double> mesh_ms, codec_ms, engine_ms, burn_ms;
  for (int i = 0; i < std::max(reps, 3); ++i) {
    auto t0 = Clock::now();
    PatchMesh mesh = mesh_scene(scene, {.target_patches = patches});
    mesh_ms.push_back(1e3 * seconds_since(t0));
    t0 = Clock::now();
    Scene back = decode_scene(encode_scene(scene), "bench");
    codec_ms.push_back(1e3 * seconds_since(t0));
    t0 = Clock::now();
    auto engine = make_cl_engine(mesh, {.device = device});
    engine_ms.push_back(1e3 * seconds_since(t0));
    t0 = Clock::now();
    Solver solver(mesh, *engine, {.seed = seed, .grid = grid});
    burn_ms.push_back(1e3 * seconds_since(t0));
  }
  row("component_ms", "none", "mesh", "median", median(mesh_ms), "ms");
  row("component_ms", "none", "scene_codec", "median", median(codec_ms), "ms");
  row("component_ms", "none", "engine", "median", median(engine_ms), "ms");
  row("component_ms", "none", "burn_in", "median", median(burn_ms), "ms");

  // Per-grant cost: grant size I with the smallest exchange (one chunk of 4096) per grant, and
  // the default run (I = end: grants of K / 8, no exchange), interleaved.
  if (!grant_sizes.empty()) {
    std::vector<uint32_t> sizes = grant_sizes;
    sizes.insert(sizes.begin(), 0);
    std::vector<double> grants, secs;
    std::vector<std::vector<double>> t(sizes.size());
    for (int i = 0; i < grant_reps; ++i)
      for (std::size_t g = 0; g < sizes.size(); ++g) {
        cluster::RunConfig gc = rc;
        if (sizes[g] > 0) {
          gc.exchange_every = sizes[g];
          gc.chunks = 4096;
          gc.fraction = 1.0 / 4096;
        }
        t[g].push_back(run_cluster(gc, 1, device, serial++).coordinate_s);
      }
    for (std::size_t g = 0; g < sizes.size(); ++g) {
      uint64_t size = sizes[g] > 0 ? sizes[g] : std::max<uint64_t>(1, bundles / 8);
      double n = std::ceil(static_cast<double>(bundles) / static_cast<double>(size));
      std::string name = sizes[g] > 0 ? fmt::format("{}", sizes[g]) : std::string("end");
      row("embedded_grants", "inproc", fmt::format("I={};grants={:.0f}", name, n), "median", median(t[g]), "s");
      grants.push_back(n);
      secs.push_back(median(t[g]));
    }
    auto [a0, slope] = fit(grants, secs);
    row("embedded_grants", "inproc", "fit", "per_grant_ms", 1e3 * slope, "ms");
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::vector<std::string> sections = {"te", "ti", "bytes", "embedded"};
    std::vector<uint32_t> sizes = {0, 1000, 10000, 100000, 1000000};
    std::vector<std::size_t> ti_patches = {5000, 10000, 20000};
    std::vector<uint32_t> grant_sizes = {1, 16, 125};
    int exchange_reps = 200, ti_bundles = 50, reps = 15, grant_reps = 3, bytes_nodes = 2, grid = 0;
    uint32_t exchange_chunks = 16, every = 16, chunks = 16;
    std::size_t patches = 10000;
    uint64_t bundles = 1000, bytes_bundles = 256, seed = 1;
    std::string device;
    for (int i = 1; i < argc; i += 2) {
      std::string k = argv[i];
      if (i + 1 >= argc) fail("flag {} needs a value", k);
      std::string v = argv[i + 1];
      if (k == "--sections") sections = split(v);
      else if (k == "--sizes") {
        sizes.clear();
        for (const auto& s : split(v)) sizes.push_back(static_cast<uint32_t>(std::stoul(s)));
      } else if (k == "--ti-patches") {
        ti_patches.clear();
        for (const auto& s : split(v)) ti_patches.push_back(std::stoul(s));
      } else if (k == "--grant-sizes") {
        grant_sizes.clear();
        for (const auto& s : split(v))
          if (s != "none") grant_sizes.push_back(static_cast<uint32_t>(std::stoul(s)));
      } else if (k == "--exchange-reps") exchange_reps = std::stoi(v);
      else if (k == "--exchange-chunks") exchange_chunks = static_cast<uint32_t>(std::stoul(v));
      else if (k == "--ti-bundles") ti_bundles = std::stoi(v);
      else if (k == "--patches") patches = std::stoul(v);
      else if (k == "--bundles") bundles = std::stoull(v);
      else if (k == "--reps") reps = std::stoi(v);
      else if (k == "--grant-reps") grant_reps = std::stoi(v);
      else if (k == "--seed") seed = std::stoull(v);
      else if (k == "--grid") grid = std::stoi(v);
      else if (k == "--bytes-nodes") bytes_nodes = std::stoi(v);
      else if (k == "--bytes-bundles") bytes_bundles = std::stoull(v);
      else if (k == "--exchange-every") every = static_cast<uint32_t>(std::stoul(v));
      else if (k == "--chunks") chunks = static_cast<uint32_t>(std::stoul(v));
      else if (k == "--device") device = v;
      else if (k == "--node-poll-ms") g_node_poll_ms = std::stoi(v);
      else fail("unknown flag {}", k);
    }
    auto has = [&](const char* s) { return std::find(sections.begin(), sections.end(), s) != sections.end(); };
    Scene cornell = load_scene("cornell");
    int serial = 0;
    std::printf("measure,transport,param,stat,value,unit\n");
    if (has("te")) bench_exchange(sizes, exchange_chunks, exchange_reps);
    if (has("ti")) bench_bundles(cornell, ti_patches, ti_bundles, seed, grid, device);
    if (has("bytes")) bench_bytes(cornell, patches, bytes_bundles, bytes_nodes, every, chunks, seed, grid, device, serial);
    if (has("embedded")) bench_embedded(cornell, patches, bundles, reps, grant_reps, seed, grid, grant_sizes, device, serial);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_cluster: error: %s\n", e.what());
    return 1;
  }
}
