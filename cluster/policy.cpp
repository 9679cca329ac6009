// sirad: the coordinator's decisions (no sockets, no clocks): see policy.h.
#include "cluster/policy.h"

#include <algorithm>
#include <limits>
#include <cmath>
#include <map>
#include <numeric>

#include <fmt/format.h>

#include "util/check.h"
#include "util/error.h"

namespace sirad::cluster {

uint64_t grant_unit(const PatchMesh& mesh, Directions directions, double shots_per_bundle) {
  uint64_t unit = sampling_plan(mesh, directions).interleave;
  if (shots_per_bundle > 0.0 && shots_per_bundle < 1.0) {
    const double k = 1.0 / shots_per_bundle;
    const uint64_t whole = static_cast<uint64_t>(std::llround(k));
    if (whole > 1 && whole <= 4096 && std::fabs(k - static_cast<double>(whole)) <= 1e-9 * k)
      unit = std::lcm(unit, whole);
  }
  return unit;
}

std::vector<double> error_weights(const PatchMesh& mesh) {
  std::vector<double> weight(mesh.size());
  double lit = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    weight[j] = mesh.emits(j) ? 0.0 : static_cast<double>(mesh.area[j]);
    lit += weight[j];
  }
  if (lit == 0)
    for (std::size_t j = 0; j < mesh.size(); ++j) weight[j] = mesh.area[j];
  return weight;
}

ExchangeSetting auto_exchange(UpdateRule rule, const model::Scene& scene, const std::vector<NodeCost>& nodes, Mode mode,
                              uint64_t bundles, uint32_t chunks, double time_limit_s, double coordinator_transfer) {
  const uint32_t P = std::max<uint32_t>(1, static_cast<uint32_t>(nodes.size()));
  std::vector<double> t;
  double t_transfer = 0, rate = 0;  // rate: the nodes' bundles per second together
  for (const NodeCost& n : nodes) {
    t.push_back(std::max(n.t_iteration, 1e-9));
    t_transfer = std::max(t_transfer, n.t_transfer);
    rate += 1 / std::max(n.t_iteration, 1e-9);
  }
  std::sort(t.begin(), t.end());
  const double t_iteration = t.empty() ? 1e-3 : t[t.size() / 2];
  uint64_t per_node = std::max<uint64_t>(1, bundles / P);
  if (time_limit_s > 0) per_node = std::clamp<uint64_t>(static_cast<uint64_t>(time_limit_s / t_iteration), 1, per_node);
  const double min_fraction = 1.0 / std::max<uint32_t>(1, chunks);
  if (rule == UpdateRule::chain) {
    // Async: a node computes its queued grant while its report travels, so the link only has to
    // keep up (transfer <= grant time); sync: the barrier waits for the transfer (<= 1/10).
    const double share = mode == Mode::async ? 1.0 : 10.0;
    double need = 1;
    for (const NodeCost& n : nodes) need = std::max(need, std::ceil(share * n.t_transfer / std::max(n.t_iteration, 1e-9)));
    // The coordinator's link carries every node's report: one state per I bundles of each node.
    need = std::max(need, std::ceil(share * coordinator_transfer * rate));
    uint64_t i = std::clamp<uint64_t>(static_cast<uint64_t>(std::min(need, 1e15)), 1, std::max<uint64_t>(1, per_node / 8));
    i = std::min<uint64_t>(i, kExchangeAuto - 1);
    return {static_cast<uint32_t>(i), 1.0,
            fmt::format("chain rule: exchanges do not change the chains, only cost; S = 1 and I = {}, the shortest period at "
                        "which every node's link {} (P {}, median T_i {:.4g} s, slowest transfer {:.4g} s{})",
                        i, mode == Mode::async ? "keeps up with its grants" : "takes under a tenth of a grant", P, t_iteration,
                        t_transfer,
                        coordinator_transfer > 0 ? fmt::format(", the coordinator's link {:.4g} s a state", coordinator_transfer)
                                                 : "")};
  }
  // T_e, charged P S T_e per exchange (eq. 1): the nodes' links carry their states side by side
  // (S times the slowest transfer, hidden behind a queued grant in async mode), the
  // coordinator's link one after another (P S of its transfers, which no grant hides).
  const double t_nodes = mode == Mode::async ? 0.0 : t_transfer / P;
  model::Costs costs{t_iteration, std::max(t_nodes, coordinator_transfer)};
  const double time = time_limit_s > 0 ? time_limit_s : static_cast<double>(per_node) * costs.t_iteration;
  model::ExchangeChoice c = model::choose_exchange(time, P, costs, scene, per_node, min_fraction);
  uint64_t i = std::clamp<uint64_t>(c.period, 1, kExchangeAuto - 1);
  return {static_cast<uint32_t>(i), c.fraction,
          fmt::format("model: P {}, a {:.3f}, sigma_1/C {:.3g}, T_i {:.4g} s, T_e {:.4g} s, T {:.4g} s: I = {}, S = {} "
                      "(predicted error {:.4g})",
                      P, scene.contraction, scene.sigma_ratio, costs.t_iteration, costs.t_exchange, time, i, c.fraction,
                      c.prediction.relative_error)};
}

double exchange_seconds(std::size_t patches, const emulation::LinkSpec* link) {
  const double bits = 24.0 * 8.0 * static_cast<double>(patches);
  if (link == nullptr) return 2 * bits / 1e9 + 2 * 1e-4;
  auto rate = [](double mbit) { return mbit > 0 ? mbit * 1e6 : 1e9; };
  return bits / rate(link->up_mbit) + bits / rate(link->down_mbit) + 2 * (link->latency_ms + link->jitter_ms) * 1e-3;
}

double coordinator_seconds(std::size_t patches, const emulation::LinkSpec& link) {
  const double bits = 24.0 * 8.0 * static_cast<double>(patches);
  auto seconds = [&](double mbit) { return mbit > 0 ? bits / (mbit * 1e6) : 0.0; };
  return std::max(seconds(link.up_mbit), seconds(link.down_mbit)) + (link.latency_ms + link.jitter_ms) * 1e-3;
}

const char* NodeState::state() const {
  return quarantined ? "quarantined" : dead ? "dead" : final_in ? "done" : !ready ? "joining" : !grants.empty() ? "working" : "waiting";
}

Policy::Policy(const PolicyConfig& config, std::vector<uint32_t> starts, std::vector<double> weight, ChunkBounds bounds)
    : config_(config), starts_(starts), weight_(std::move(weight)), ledger_(config.bundles), aggregate_(starts, 0),
      plausible_(std::move(starts), std::move(bounds), config.batch_bundles, config.rule == UpdateRule::chain) {
  if (config_.grant_unit == 0) config_.grant_unit = 1;
}

PolicySnapshot Policy::snapshot() const {
  PolicySnapshot s;
  for (uint32_t n = 0; n < nodes(); ++n) {
    NodeRecord r;
    r.state = nodes_[n];
    for (uint32_t c = 0; c < aggregate_.chunks(); ++c) r.parts.push_back(aggregate_.state(n, c));
    r.done = ledger_.done_by(n);
    s.nodes.push_back(std::move(r));
  }
  s.exchange_every = config_.exchange_every;
  s.fraction = config_.fraction;
  s.exchange_why = exchange_why_;
  s.exchanges = exchanges_;
  s.reports = reports_;
  s.closing = closing_;
  s.ended_by = ended_by_;
  return s;
}

void Policy::restore(const PolicySnapshot& s) {
  SIRAD_CHECK(nodes() == 0, "restore: the run already has nodes");
  if (s.exchange_every == kExchangeAuto || !(s.fraction > 0 && s.fraction <= 1)) fail("restore: invalid exchange setting");
  std::map<uint32_t, std::vector<Range>> done;
  for (uint32_t n = 0; n < s.nodes.size(); ++n) {
    const NodeRecord& r = s.nodes[n];
    join();
    if (r.parts.size() != aggregate_.chunks()) fail("restore: node {} has {} chunks, the run {}", n, r.parts.size(), aggregate_.chunks());
    for (uint32_t c = 0; c < aggregate_.chunks(); ++c) aggregate_.set(n, c, r.parts[c].sum, r.parts[c].count);
    NodeState& p = nodes_[n];
    p = r.state;
    p.ready = true;
    p.dead = true;
    p.grants.clear();
    done[n] = r.done;
  }
  ledger_ = Ledger::from_record(config_.bundles, done);
  config_.exchange_every = s.exchange_every;
  config_.fraction = s.fraction;
  exchange_why_ = s.exchange_why;
  exchanges_ = s.exchanges;
  reports_ = last_error_check_ = s.reports;
  closing_ = s.closing;
  ended_by_ = s.ended_by;
  started_ = true;  // min_nodes gated the first grant of the run, long ago
}

uint32_t Policy::join() {
  if (nodes() < kMaxNodeEntries) {
    nodes_.emplace_back();
    bundle_time_.push_back(0.0);
    aggregate_.add_node();
    plausible_.add_node();
    return nodes() - 1;
  }
  for (uint32_t n = 0; n < nodes(); ++n) {
    const NodeState& p = nodes_[n];
    if (p.dead && aggregate_.holds_nothing(n) && ledger_.done_by(n).empty() && ledger_.outstanding(n) == 0) {
      nodes_[n] = NodeState{};
      bundle_time_[n] = 0.0;
      aggregate_.clear(n);
      plausible_.forget(n);
      return n;
    }
  }
  fail("the run has {} node entries, each holding data: no more nodes can join", kMaxNodeEntries);
}

void Policy::ready(uint32_t n) {
  NodeState& p = nodes_.at(n);
  if (p.ready) fail("READY twice");
  p.ready = true;
}

uint64_t Policy::dead(uint32_t n) {
  NodeState& p = nodes_.at(n);
  uint64_t back = ledger_.outstanding(n);
  ledger_.abandon(n);
  p.dead = true;
  p.grants.clear();
  return back;
}

uint64_t Policy::lost(uint32_t n, const std::string& who) {
  const uint64_t back = ledger_.outstanding(n);
  ledger_.lose(n, who);  // and back to the budget
  if (std::optional<Range> r = ledger_.poisoned(kMaxBundleLosses)) close(lost_reason(*r));
  dead(n);
  return back;
}

std::string Policy::lost_reason(const Range& bundles) {
  return fmt::format("bundles {}..{} were lost with {} nodes, each gone while it ran them: they may crash whoever runs them, "
                     "so the run ended with the bundles done",
                     bundles.first, bundles.last - 1, kMaxBundleLosses);
}

uint64_t Policy::grant_size() const {
  uint64_t n = config_.exchange_every > 0 ? config_.exchange_every
                                          : std::max<uint64_t>(1, config_.bundles / (8 * std::max<uint32_t>(1, nodes())));
  // A run that ends at a target error or a time limit hears of it with each report (no
  // grant goes out after the limit, and the run ends when the last is in): without exchanges,
  // a report (no chunks, a few bytes) every kTargetReportBundles at the most.
  if (config_.exchange_every == 0 && (config_.target_error > 0 || config_.time_limit_s > 0))
    n = std::min<uint64_t>(n, kTargetReportBundles);
  // Whole multiples of the grant unit, so ranges start at multiples of it (the ledger hands out
  // its free ranges from the front).
  return (n + config_.grant_unit - 1) / config_.grant_unit * config_.grant_unit;
}

void Policy::set_bundle_time(uint32_t n, double seconds) {
  bundle_time_.at(n) = std::isfinite(seconds) && seconds > 0 ? seconds : 0.0;
}

double Policy::grant_time_bound(uint32_t n, uint64_t bundles, double claimed_s) const {
  constexpr double kSlack = 8, kSpread = 16, kMaxBundleS = 10;
  double t = bundle_time_.at(n) > 0 ? bundle_time_[n] : std::isfinite(claimed_s) && claimed_s > 0 ? claimed_s : 1.0;
  double fastest = std::numeric_limits<double>::infinity();
  for (uint32_t m = 0; m < nodes(); ++m)
    if (!nodes_[m].dead && nodes_[m].ready && bundle_time_[m] > 0) fastest = std::min(fastest, bundle_time_[m]);
  t = std::min({t, kSpread * fastest, kMaxBundleS});
  return kSlack * static_cast<double>(bundles) * t;
}

uint64_t Policy::balanced_size(uint32_t n) const {
  const uint64_t base = grant_size();
  if (!config_.balance || n >= nodes() || bundle_time_[n] <= 0) return base;
  std::vector<double> t;
  for (uint32_t m = 0; m < nodes(); ++m)
    if (!nodes_[m].dead && nodes_[m].ready && bundle_time_[m] > 0) t.push_back(bundle_time_[m]);
  if (t.size() < 2) return base;
  const double fastest = *std::min_element(t.begin(), t.end());
  const double f = std::exp2(-std::min(4.0, std::floor(std::log2(bundle_time_[n] / fastest) + 1e-9)));
  const double size = std::max(1.0, std::round(static_cast<double>(base) * f));
  const uint64_t u = config_.grant_unit;
  return (static_cast<uint64_t>(size) + u - 1) / u * u;
}

double Policy::speed_share(uint32_t n) const {
  // Speeds 1 / t of the live ready nodes; one not measured yet counts as their mean.
  double known = 0, sum = 0;
  uint32_t count = 0, unknown = 0;
  for (uint32_t m = 0; m < nodes(); ++m) {
    const NodeState& p = nodes_[m];
    if (p.dead || !p.ready || p.stopped) continue;
    if (bundle_time_[m] > 0) known += 1.0 / bundle_time_[m], ++count;
    else ++unknown;
  }
  const double mean = count ? known / count : 1.0;
  sum = known + mean * unknown;
  const double own = n < nodes() && bundle_time_[n] > 0 ? 1.0 / bundle_time_[n] : mean;
  return sum > 0 ? own / sum : 1.0;
}

uint64_t Policy::grant_size(uint32_t n) const {
  const uint64_t size = balanced_size(n);
  // Guided self-scheduling: near the end each grant is at most half this node's share (by
  // speed) of the bundles not granted yet, so grants shrink as the budget runs out and the
  // nodes run out of work together, within a bundle or two, instead of waiting on the last
  // full-size grant. Below one grant unit the last grants are split further, down to a single
  // bundle: the few bundles of a stratified block that may then run fewer than G chain steps
  // apart bias the estimate by far less than anything measurable (DESIGN.md, "the ledger's
  // tail"), and the k steps of a shot that end on two nodes are only correlated, not biased.
  // Sync runs keep their period to the end: every round is a barrier anyway, sized by speed.
  if (config_.mode != Mode::async) return size;
  const double guided = std::ceil(static_cast<double>(ledger_.available()) * speed_share(n) / 2.0);
  if (guided >= static_cast<double>(size)) return size;
  const uint64_t u = config_.grant_unit, g = static_cast<uint64_t>(std::max(1.0, guided));
  return g >= u ? g / u * u : g;
}

uint64_t Policy::quarantine(uint32_t n, const std::string& why) {
  NodeState& p = nodes_.at(n);
  uint64_t done = ledger_.revoke(n);
  aggregate_.clear(n);
  plausible_.clear(n);
  p.dead = p.quarantined = true;
  p.why = why;
  p.grants.clear();
  p.bundles = 0;
  p.error = -1;
  p.error_bundles = 0;
  return done;
}

void Policy::quarantine_and_fail(uint32_t n, const std::string& why) {
  uint64_t done = quarantine(n, why);
  fail("quarantined: {}; its {} bundles return to the budget and its data are dropped", why, done);
}

Orders Policy::next_work() {
  Orders orders;
  uint32_t ready = 0;
  bool any_holding = false;
  for (const NodeState& p : nodes_) {
    if (p.dead) continue;
    ready += p.ready && !p.stopped;
    any_holding = any_holding || (p.ready && !p.grants.empty());
  }
  if (!started_ && ready < config_.min_nodes) return orders;  // min_nodes gates the first grant only
  if (!started_ && config_.exchange_every == kExchangeAuto) {
    std::vector<uint32_t> ready_nodes;
    for (uint32_t n = 0; n < nodes(); ++n)
      if (!nodes_[n].dead && nodes_[n].ready) ready_nodes.push_back(n);
    ExchangeSetting s = config_.choose ? config_.choose(ready_nodes) : ExchangeSetting{0, 1.0, "no chooser: states at the end"};
    SIRAD_CHECK(s.exchange_every != kExchangeAuto && s.fraction > 0 && s.fraction <= 1, "auto exchange chose an invalid setting");
    config_.exchange_every = s.exchange_every;
    config_.fraction = s.fraction;
    exchange_why_ = s.why;
  }
  started_ = true;
  if (config_.mode == Mode::sync && any_holding) return orders;
  std::size_t depth = config_.mode == Mode::async && ledger_.available() >= 2 * ready * grant_size() ? 2 : 1;
  for (uint32_t n = 0; n < nodes(); ++n) {
    NodeState& p = nodes_[n];
    while (!closing_ && !p.dead && p.ready && !p.stopped && p.grants.size() < depth) {
      auto ranges = ledger_.grant(n, grant_size(n));
      if (ranges.empty()) break;
      GrantOrder g{n, ++grants_, std::move(ranges), {}};
      if (config_.exchange_every > 0) g.report_chunks = exchange_chunks(p.rotation++, config_.fraction, aggregate_.chunks());
      p.grants.push_back(g.id);
      orders.grants.push_back(std::move(g));
    }
  }
  if (ending())  // not before: a dead node's grant may still come back to the budget
    for (uint32_t n = 0; n < nodes(); ++n) {
      NodeState& p = nodes_[n];
      if (!p.dead && p.ready && !p.stopped && p.grants.empty()) {
        p.stopped = true;
        orders.stops.push_back(n);
      }
    }
  return orders;
}

void Policy::take_chunks(uint32_t n, std::vector<ChunkState>& chunks) {
  NodeState& p = nodes_.at(n);
  std::vector<bool> seen(aggregate_.chunks(), false);
  double suspicion = p.suspicion;
  std::vector<Plausibility::Observation> seen_as;
  for (const ChunkState& c : chunks) {
    try {
      aggregate_.check(n, c.chunk, c.sum, c.count);
    } catch (const Error& e) {
      quarantine_and_fail(n, e.what());
    }
    // A node's count of a chunk is the bundles its chain has run (solver/solver.h): never more
    // than the bundles the ledger says it has done.
    if (c.count > p.bundles) quarantine_and_fail(n, fmt::format("chunk {} count {} exceeds its {} bundles", c.chunk, c.count, p.bundles));
    if (seen[c.chunk]) quarantine_and_fail(n, fmt::format("chunk {} twice in one message", c.chunk));
    seen[c.chunk] = true;
    seen_as.push_back(plausible_.observe(c.chunk, c.sum, c.count));
    Plausibility::Verdict v = plausible_.assess(n, c.chunk, seen_as.back());
    if (!v.why.empty()) quarantine_and_fail(n, v.why);
    suspicion = std::max(suspicion, v.score);
  }
  p.suspicion = suspicion;
  for (std::size_t i = 0; i < chunks.size(); ++i) {
    plausible_.take(n, chunks[i].chunk, seen_as[i]);
    aggregate_.set(n, chunks[i].chunk, std::move(chunks[i].sum), chunks[i].count);
  }
}

std::optional<Exchange> Policy::take_result(uint32_t n, uint64_t grant_id, const std::vector<Range>& done,
                                       std::vector<ChunkState> chunks, double error_estimate) {
  NodeState& p = nodes_.at(n);
  if (p.dead) fail("report from a node declared dead");
  if (p.grants.empty() || grant_id != p.grants.front()) fail("report for grant {} it does not hold", grant_id);
  p.grants.erase(p.grants.begin());  // answered, whatever follows: a refused report must not wedge the run
  for (const Range& d : done) {
    try {
      ledger_.done(n, d);
    } catch (const Error& e) {
      quarantine_and_fail(n, e.what());
    }
    p.bundles += d.size();
  }
  if (!std::isfinite(error_estimate) || error_estimate > 1e6)
    quarantine_and_fail(n, fmt::format("REPORT error estimate {} is not a finite relative error", error_estimate));
  take_chunks(n, chunks);
  if (error_estimate > 0) {
    p.error = error_estimate;
    p.error_bundles = p.bundles;  // the node's chain had run this many when it estimated
  }
  ++reports_;
  if (chunks.empty()) return std::nullopt;
  // The exchange: the others' aggregate (star) or the next node's state (ring).
  Exchange x;
  x.exchange = p.exchanges++;
  for (const ChunkState& c : chunks) {
    x.chunks.push_back(c.chunk);
    x.parts.push_back(aggregate_.others(n, c.chunk, config_.topology));
  }
  ++exchanges_;
  return x;
}

void Policy::final_state(uint32_t n, std::vector<ChunkState> chunks) {
  NodeState& p = nodes_.at(n);
  if (p.dead) fail("FINAL from a node declared dead");
  if (!p.stopped || p.final_in) fail("FINAL without STOP");
  take_chunks(n, chunks);
  p.final_in = true;
}

std::string CloseRule::check(double elapsed_s, double estimate) const {
  if (time_limit_s > 0 && elapsed_s >= time_limit_s) return "time limit";
  if (target_error > 0 && estimate >= 0 && estimate <= target_error)
    return fmt::format("target error ({:.4g} <= {:.4g})", estimate, target_error);
  return "";
}

bool Policy::check_close(double elapsed_s) {
  if (closing_ || ledger_.finished()) return false;
  const CloseRule rule{config_.time_limit_s, config_.target_error};
  // The estimate only when a report came in since the last look (it changes only then).
  double estimate = -1;
  if (rule.wants_estimate() && reports_ > last_error_check_) {
    last_error_check_ = reports_;
    estimate = error_estimate();
  }
  ended_by_ = rule.check(elapsed_s, estimate);
  if (ended_by_.empty()) return false;
  closing_ = true;
  return true;
}

bool Policy::close(const std::string& why) {
  if (closing_ || ledger_.finished()) return false;
  ended_by_ = why;
  closing_ = true;
  return true;
}

bool Policy::ending() const {
  if (ledger_.finished()) return true;
  if (!closing_) return false;
  for (const NodeState& p : nodes_)
    if (!p.dead && !p.grants.empty()) return false;
  return true;
}

bool Policy::done() const {
  if (!ending()) return false;
  for (const NodeState& p : nodes_)
    if (!p.dead && p.ready && !p.final_in) return false;
  return true;
}

// Under the chain rule the nodes are independent chains and the result is their count-weighted
// mean: its relative error combines each node's own batch-means estimate e_p, weighted by the
// counts the aggregate holds for it (Aggregate::combined_error; every node holding data must
// have an estimate); otherwise (the average rule couples the nodes, or a node has too few
// bundles yet) the spread of the node states (Aggregate::spread_error).
// A node's estimate is its own word: the nodes run one algorithm, so their error per bundle,
// e_p sqrt(n_p), is one value up to the noise of batch means (tens of per cent); none counts
// for less than half the nodes' median of it, so a node that claims to be exact cannot end a
// run at its target early (and honest ones are not touched).
double Policy::error_estimate() const {
  if (config_.rule == UpdateRule::chain) {
    std::vector<double> error(nodes(), -1.0), per_bundle;
    std::vector<uint64_t> bundles(nodes(), 0);
    for (uint32_t n = 0; n < nodes(); ++n) {
      error[n] = nodes_[n].error;
      bundles[n] = nodes_[n].error_bundles;
      if (error[n] > 0 && bundles[n] > 0) per_bundle.push_back(error[n] * std::sqrt(static_cast<double>(bundles[n])));
    }
    if (!per_bundle.empty()) {
      std::sort(per_bundle.begin(), per_bundle.end());
      const std::size_t k = per_bundle.size();
      const double median = k % 2 ? per_bundle[k / 2] : 0.5 * (per_bundle[k / 2 - 1] + per_bundle[k / 2]);
      for (uint32_t n = 0; n < nodes(); ++n)
        if (error[n] > 0 && bundles[n] > 0) error[n] = std::max(error[n], 0.5 * median / std::sqrt(static_cast<double>(bundles[n])));
    }
    double e = aggregate_.combined_error(error, bundles, weight_);
    if (e > 0) return e;
    const double spread = aggregate_.spread_error(weight_);
    if (spread >= 0) return spread;
    // No states held from two nodes yet (exchanges only at the end): the count-weighted mean of
    // independent chains has the relative error sqrt(sum n_p^2 e_p^2) / sum n_p, from every
    // node that has run bundles (none may lack an estimate).
    double v = 0, n = 0;
    for (uint32_t p = 0; p < nodes(); ++p) {
      if (nodes_[p].quarantined || nodes_[p].bundles == 0) continue;
      if (!(error[p] > 0) || bundles[p] == 0) return spread;
      const double m = static_cast<double>(bundles[p]);
      v += m * m * error[p] * error[p];
      n += m;
    }
    return n > 0 ? std::sqrt(v) / n : spread;
  }
  return aggregate_.spread_error(weight_);
}

std::vector<glm::vec3> Policy::radiosity() const {
  std::vector<glm::vec3> out(starts_.back());
  for (uint32_t c = 0; c + 1 < starts_.size(); ++c) {
    std::vector<double> est = aggregate_.estimate(c);
    for (uint32_t j = starts_[c]; j < starts_[c + 1]; ++j) {
      std::size_t i = 3 * static_cast<std::size_t>(j - starts_[c]);
      out[j] = glm::vec3(static_cast<float>(est[i]), static_cast<float>(est[i + 1]), static_cast<float>(est[i + 2]));
    }
  }
  return out;
}

}  // namespace sirad::cluster
