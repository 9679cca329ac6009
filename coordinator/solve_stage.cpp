// sirad: the coordinator's solve stage (session.h): READY, grants and their due times, reports
// and their exchanges, final states, the nodes' liveness during the bundles.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cluster/exchange.h"
#include "coordinator/session.h"
#include "util/limits.h"

namespace sirad::cluster::detail {

// The solve (PROTOCOL.md section 3): the bundles of the Policy's grants. Each turn writes the
// checkpoint and the preview on their periods, judges liveness and grants' due times
// (keep_alive) and closes the run when the policy says; each message goes to handle(), and
// one it refuses is answered by an ERROR and logged: the run goes on.
class Coordinator::SolveStage final : public Coordinator::Stage {
 public:
  explicit SolveStage(Coordinator& c) : c_(c) {}
  bool finished() const override { return c_.policy_.done(); }
  [[noreturn]] void out_of_time() override {
    fail("run did not finish within {} s ({} of {} bundles done)", c_.config_.timeout_s, c_.policy_.ledger().done_count(),
         c_.config_.bundles);
  }

  bool turn(Clock::time_point now) override {
    const RunConfig& config = c_.config_;
    if (!config.checkpoint.empty() && seconds(now - last_checkpoint_) >= config.checkpoint_every_s) {
      last_checkpoint_ = now;
      try {
        c_.checkpoint();
      } catch (const Error& e) {  // a full disk must not end the run; the last good file stays
        c_.say(logging::Level::warn, fmt::format("checkpoint not written: {}; the run goes on", e.what()), {{"event", "checkpoint"}});
      }
    }
    if (config.preview && seconds(now - last_preview_) >= config.preview_every_s && c_.holds_states()) {
      last_preview_ = now;
      config.preview(c_.policy_.radiosity());
    }
    c_.keep_alive(now);
    Policy& policy = c_.policy_;
    if ((config.close && config.close->load() && policy.close("interrupted")) || policy.check_close(seconds(now - c_.start_))) {
      c_.say(logging::Level::info,
             fmt::format("{} reached after {} bundles: finishing the outstanding grants", policy.ended_by(), policy.ledger().done_count()),
             {{"event", "closing"}, {"ended_by", policy.ended_by()}, {"bundles", policy.ledger().done_count()}});
      c_.schedule();
    }
    return false;
  }

  void message(const proto::Received& in, const std::string& key) override {
    const std::string& id = in.frames.front();
    std::optional<Message> m = c_.decoded(in);
    if (!m) return;
    try {
      c_.handle(id, key, in.address, *m);
    } catch (const Error& e) {
      if (c_.config_.strict) throw;
      c_.log(id, e.what());
      c_.error(id, e.what(), dynamic_cast<const Rejoin*>(&e) != nullptr);
      // A quarantine sticks to the node's key (under CURVE), not only to its routing id.
      if (auto it = c_.peers_.find(id); it != c_.peers_.end() && c_.policy_.node(it->second.index).quarantined && !key.empty())
        c_.record_.quarantined_keys.insert(key);
    }
  }

 private:
  Coordinator& c_;
  Clock::time_point last_checkpoint_ = Clock::now(), last_preview_ = Clock::now();
};

void Coordinator::tighten_first_grants(const Peer& measured) {
  const auto now = Clock::now();
  const double t = seconds(now - measured.first_grant_at);
  if (measured.first_grant_at == Clock::time_point{} || !(t < first_grant_s_)) return;
  first_grant_s_ = t;
  std::vector<uint32_t> unmeasured;
  for (const auto& [id, q] : peers_)
    if (!rendering(q) && policy_.node(q.index).bundles == 0 && !policy_.node(q.index).dead) unmeasured.push_back(q.index);
  if (grants_.tighten(unmeasured, clock(now), t))
    say(logging::Level::info, fmt::format("first grants now due within {:.1f} s of now ({} times {}'s first grant, {:.3f} s)",
                                          grants_.rules().slack_s + grants_.rules().unequal_first * t,
                                          grants_.rules().unequal_first, measured.name, t),
        {{"event", "first grants due"}, {"first_grant_s", t}});
}

double Coordinator::first_grant_allowance() const {
  return std::min(grants_.rules().first_grant_s, grants_.rules().unequal_first * first_grant_s_);
}

ExchangeSetting Coordinator::choose(const std::vector<uint32_t>& ready) {
  std::vector<NodeCost> costs;
  for (uint32_t n : ready) {
    const Peer& p = peer(n);
    std::optional<emulation::LinkSpec> spec;
    if (config_.profile) spec = config_.profile->for_node(n, p.name);
    double t = p.ms_per_bundle > 0 && std::isfinite(p.ms_per_bundle) ? p.ms_per_bundle / 1e3 : 0.01;
    costs.push_back({t, exchange_seconds(mesh_.size(), spec ? &*spec : nullptr)});
  }
  ExchangeSetting s = auto_setting(config_, mesh_, costs, policy_.aggregate().chunks());
  say(logging::Level::info, fmt::format("--exchange-every auto: {}", s.why),
      {{"event", "exchange"}, {"exchange_every", s.exchange_every}, {"fraction", s.fraction}});
  return s;
}

bool Coordinator::holds_states() const {
  for (uint32_t c = 0; c < policy_.aggregate().chunks(); ++c)
    if (policy_.aggregate().count(c) > 0) return true;
  return false;
}

void Coordinator::keep_alive(Clock::time_point now) {
  for (auto& [id, p] : peers_) {
    const NodeState& n = policy_.node(p.index);
    if (n.dead) continue;
    if (n.final_in) {  // done with the run; waiting for the image, it hears from us meanwhile
      // Bundles to run again (a node quarantined at its FINAL gave them back): a node that
      // waits for the image says no HELLO by itself, so it is asked to, and rejoins.
      if (imaging() && !policy_.closing() && policy_.ledger().available() > 0 && !p.asked_rejoin) {
        p.asked_rejoin = true;
        wire::Error e;
        e.set_reason("bundles to run again; say HELLO");
        e.set_rejoin(true);
        send(p, {Command::error, e, {}});
      }
      if (imaging()) keep_in_touch(p, now);
      else p.down.flush(router_, clock(now));
      continue;
    }
    if (std::string why = gone(p, n.ready); !why.empty()) declare_dead(p, why, true);
    else keep_in_touch(p, now);
  }
}

void Coordinator::declare_dead(Peer& p, const std::string& why, bool gone) {
  const bool poisoned_before = policy_.ledger().poisoned(Policy::kMaxBundleLosses).has_value();
  const uint64_t back = gone && !disconnected_on_purpose(p) ? policy_.lost(p.index, p.key.empty() ? p.address : p.key)
                                                            : policy_.dead(p.index);
  p.dead_why = why;
  p.down.clear();
  grants_.clear(p.index);
  log(p.id, fmt::format("declared dead ({}); {} granted bundles return to the budget", why, back));
  if (!poisoned_before && policy_.ledger().poisoned(Policy::kMaxBundleLosses))
    say(logging::Level::error, policy_.ended_by(), {{"event", "bundles lost"}});
  schedule();  // a sync barrier may have been waiting on it
}

bool Coordinator::disconnected_on_purpose(const Peer& p) const {
  if (!config_.profile || p.ready_at == Clock::time_point{}) return false;
  const double at = config_.profile->for_node(p.index, p.name).disconnect_at_s;
  return at >= 0 && seconds(Clock::now() - p.ready_at) >= at;
}

void Coordinator::handle(const std::string& id, const std::string& key, const std::string& address, const Message& m) {
  if (m.command == Command::hello) return hello(id, key, address, std::get<wire::Hello>(m.header));
  auto it = peers_.find(id);
  if (it == peers_.end()) throw Rejoin(fmt::format("{} before HELLO", proto::command_name(m.command)));
  Peer& p = it->second;
  // Under CURVE a peer is its key: another key on its routing id (a node that took it over)
  // is refused without touching the node that has it.
  if (p.key != key) fail("{} on the routing id of {} from another key: refused", proto::command_name(m.command), p.name);
  const NodeState& n = policy_.node(p.index);
  if (n.quarantined) fail("{} from a quarantined node ({})", proto::command_name(m.command), n.why);
  if (n.dead) throw Rejoin(fmt::format("{} from a node declared dead; say HELLO to rejoin", proto::command_name(m.command)));
  p.last_seen = Clock::now();
  switch (m.command) {
    case Command::ready: ready(p, std::get<wire::Ready>(m.header)); break;
    case Command::report: report(p, std::get<wire::Report>(m.header), m.bulk); break;
    case Command::final_state: final_state(p, std::get<wire::Report>(m.header), m.bulk); break;
    case Command::error:
      if (config_.strict) fail("{}: {}", p.name, peer_text(std::get<wire::Error>(m.header).reason(), kPeerTextBytes));
      log(id, "node: " + peer_text(std::get<wire::Error>(m.header).reason(), kPeerTextBytes));
      break;
    case Command::heartbeat: break;
    default: fail("unexpected {}", proto::command_name(m.command));
  }
}

void Coordinator::ready(Peer& p, const wire::Ready& r) {
  if (r.run_id() != run_.run_id()) fail("READY for run {:x}, not this run", r.run_id());
  policy_.ready(p.index);
  p.ready_at = Clock::now();
  p.ms_per_bundle = r.ms_per_bundle();
  say(logging::Level::info, fmt::format("{} ready: {:.2f} ms per bundle", p.name, p.ms_per_bundle),
      {{"event", "ready"}, {"peer", p.name}, {"ms_per_bundle", p.ms_per_bundle}});
  schedule();
}

void Coordinator::schedule() {
  Orders orders = policy_.next_work();
  for (const GrantOrder& o : orders.grants) {
    wire::Grant g = grant_of(o.id, o.ranges);
    for (uint32_t c : o.report_chunks) g.add_report_chunks(c);
    Peer& p = peer(o.node);
    uint64_t bundles = 0;
    for (const Range& r : o.ranges) bundles += r.size();
    const auto now = Clock::now();
    const double bound = policy_.grant_time_bound(p.index, bundles, p.ms_per_bundle / 1e3);
    const double first = policy_.node(p.index).bundles == 0 ? first_grant_allowance() : 0.0;
    if (p.first_grant_at == Clock::time_point{}) p.first_grant_at = now;
    grants_.add(p.index, o.id, clock(now), bound + first);
    send(p, {Command::grant, g, {}});
  }
  for (uint32_t n : orders.stops) {
    wire::Stop s;
    s.set_run_id(run_.run_id());
    s.set_image_follows(imaging());
    send(peer(n), {Command::stop, s, {}});
  }
}

Peer& Coordinator::peer(uint32_t index) {
  for (auto& [id, p] : peers_)
    if (p.index == index) return p;
  fail("no peer with index {}", index);  // the policy orders only current peers
}

std::vector<ChunkState> Coordinator::chunk_states(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk, uint64_t& bytes) {
  if (r.run_id() != run_.run_id()) fail("{} for run {:x}, not this run", "state", r.run_id());
  std::vector<ChunkState> out;
  for (int i = 0; i < r.chunks_size(); ++i) {
    out.push_back({r.chunks(i), proto::unpack(bulk[i]), r.counts(i)});
    bytes += bulk[i].size();
  }
  // Times a node reports are its own word: taken only within [0, kMaxSeconds].
  auto plausible = [](double t) { return t >= 0 && t <= kMaxSeconds; };
  if (plausible(r.busy_s()) && plausible(r.idle_s())) {
    p.busy_s = std::max(p.busy_s, r.busy_s());
    p.idle_s = std::max(p.idle_s, r.idle_s());
  }
  return out;
}

void Coordinator::report(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
  std::optional<Exchange> x;
  try {
    std::vector<Range> done;
    for (const auto& d : r.done()) done.push_back({d.first(), d.last()});
    // A report for a grant it does not hold is refused before its data is looked at; one for
    // its grant whose data is refused still answers the grant, without the data.
    uint64_t bytes = 0;
    std::vector<ChunkState> chunks;
    std::string refused;
    const NodeState& n = policy_.node(p.index);
    // Another run's id on the grant it holds: no honest node sends that, and nothing of it
    // may count (its done ranges included).
    if (r.run_id() != run_.run_id() && !n.grants.empty() && r.grant_id() == n.grants.front()) {
      const std::string why = fmt::format("REPORT for grant {} names run {:x}, not this run", r.grant_id(), r.run_id());
      policy_.quarantine(p.index, why);
      grants_.clear(p.index);
      fail("{}: quarantined", why);
    }
    if (!n.grants.empty() && r.grant_id() == n.grants.front()) {
      try {
        chunks = chunk_states(p, r, bulk, bytes);
      } catch (const Error& e) {
        refused = e.what();
        chunks.clear();
      }
    }
    x = policy_.take_result(p.index, r.grant_id(), done, std::move(chunks), refused.empty() ? r.error_estimate() : 0.0);
    grants_.settle(p.index, r.grant_id());
    if (!refused.empty()) throw Error(refused);
    record_.bytes_in += bytes;
    p.bytes_in += bytes;
  } catch (const Error&) {
    schedule();  // refused (the caller logs it and answers ERROR); the others go on
    throw;
  }
  record_.crossings += r.crossings();
  // Its speed as it runs, for balanced grants: busy time (emulated slowdown included) over
  // bundles since its first report (the first grant carries the kernels' compilation).
  if (uint64_t b = policy_.node(p.index).bundles; b > 0) {
    if (p.first_bundles == 0) {
      p.first_bundles = b, p.first_busy_s = p.busy_s;
      tighten_first_grants(p);
    }
    else if (b > p.first_bundles) policy_.set_bundle_time(p.index, (p.busy_s - p.first_busy_s) / static_cast<double>(b - p.first_bundles));
  }
  if (config_.progress) config_.progress(policy_.ledger().done_count(), config_.bundles);
  if (x) {
    // The exchange: the others' aggregate (star) or the next node's state (ring).
    wire::Update u;
    u.set_run_id(run_.run_id());
    u.set_exchange(x->exchange);
    std::vector<std::string> frames;
    for (std::size_t i = 0; i < x->chunks.size(); ++i) {
      u.add_chunks(x->chunks[i]);
      u.add_counts(x->parts[i].count);
      frames.push_back(proto::pack(x->parts[i].sum));
      record_.bytes_out += frames.back().size();
      p.bytes_out += frames.back().size();
    }
    send(p, {Command::update, u, frames});
  }
  schedule();
}

void Coordinator::final_state(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
  if (!policy_.node(p.index).stopped) fail("FINAL without STOP");
  try {
    uint64_t bytes = 0;
    policy_.final_state(p.index, chunk_states(p, r, bulk, bytes));
    record_.final_bytes += bytes;
    p.bytes_in += bytes;
  } catch (const Error&) {
    schedule();  // a quarantine gave bundles back
    throw;
  }
}

std::unique_ptr<Coordinator::Stage> Coordinator::solve_stage() { return std::make_unique<SolveStage>(*this); }

}  // namespace sirad::cluster::detail
