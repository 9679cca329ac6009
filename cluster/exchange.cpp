// sirad: bundle ledger, chunked per-node states and the exchange schedule (no sockets, no clocks).
#include "cluster/exchange.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/check.h"
#include "util/error.h"

namespace sirad::cluster {

Topology parse_topology(const std::string& s) {
  if (s == "star") return Topology::star;
  if (s == "ring") return Topology::ring;
  fail("topology '{}' is not star or ring", s);
}

Mode parse_mode(const std::string& s) {
  if (s == "sync") return Mode::sync;
  if (s == "async") return Mode::async;
  fail("mode '{}' is not sync or async", s);
}

uint32_t parse_exchange_every(const std::string& s) {
  if (s == "end") return 0;
  if (s == "auto") return kExchangeAuto;
  std::size_t used = 0;
  unsigned long v = 0;
  try {
    v = std::stoul(s, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != s.size() || s.empty() || s[0] == '-' || v == 0 || v >= kExchangeAuto)
    fail("'{}' is not a bundle count >= 1, 'end' or 'auto'", s);
  return static_cast<uint32_t>(v);
}

std::string exchange_every_name(uint32_t e) {
  return e == 0 ? "end" : e == kExchangeAuto ? "auto" : std::to_string(e);
}

Ledger::Ledger(uint64_t bundles) : bundles_(bundles) {
  if (bundles > 0) free_.push_back({0, bundles});
}

std::vector<Range> Ledger::grant(uint32_t node, uint64_t count) {
  std::vector<Range> out;
  while (count > 0 && !free_.empty()) {
    Range& f = free_.front();
    Range g{f.first, f.first + std::min(count, f.size())};
    f.first = g.last;
    if (f.size() == 0) free_.erase(free_.begin());
    count -= g.size();
    out.push_back(g);
    granted_[node].push_back(g);
  }
  return out;
}

bool Ledger::grant_index(uint32_t node, uint64_t index) {
  auto it = std::upper_bound(free_.begin(), free_.end(), index, [](uint64_t i, const Range& r) { return i < r.first; });
  if (it == free_.begin() || index >= std::prev(it)->last) return false;
  --it;
  const Range f = *it;
  it = free_.erase(it);
  if (index + 1 < f.last) it = free_.insert(it, {index + 1, f.last});
  if (f.first < index) free_.insert(it, {f.first, index});
  granted_[node].push_back({index, index + 1});
  return true;
}

uint64_t Ledger::available() const {
  uint64_t n = 0;
  for (const Range& f : free_) n += f.size();
  return n;
}

void Ledger::done(uint32_t node, Range r) {
  if (r.last <= r.first) fail("ledger: empty or reversed range [{}, {}) from node {}", r.first, r.last, node);
  auto it = granted_.find(node);
  if (it == granted_.end()) fail("ledger: node {} reports bundle {} it holds no grant for", node, r.first);
  auto& held = it->second;
  // The range must lie inside one held range (grants are handed out as whole ranges and
  // reported in pieces of them).
  auto h = std::find_if(held.begin(), held.end(), [&](const Range& g) { return g.first <= r.first && r.last <= g.last; });
  if (h == held.end()) fail("ledger: node {} reports bundles [{}, {}) not granted to it or already done", node, r.first, r.last);
  Range before{h->first, r.first}, after{r.last, h->last};
  held.erase(h);
  if (before.size()) held.push_back(before);
  if (after.size()) held.push_back(after);
  done_[node].push_back(r);
  done_count_ += r.size();
}

namespace {
// Sorted by first index, adjacent ranges joined.
std::vector<Range> merged(std::vector<Range> ranges) {
  std::sort(ranges.begin(), ranges.end(), [](const Range& a, const Range& b) { return a.first < b.first; });
  std::vector<Range> out;
  for (const Range& r : ranges) {
    if (!out.empty() && out.back().last == r.first) out.back().last = r.last;
    else out.push_back(r);
  }
  return out;
}
}  // namespace

void Ledger::abandon(uint32_t node) {
  auto it = granted_.find(node);
  if (it == granted_.end()) return;
  for (const Range& r : it->second) free_.push_back(r);
  granted_.erase(it);
  free_ = merged(std::move(free_));  // the lowest indices go out first
}

void Ledger::lose(uint32_t node, const std::string& who) {
  auto it = granted_.find(node);
  if (it == granted_.end()) return;
  // Splits the loss entry holding index x (if any) so that one starts at x.
  const auto split = [&](uint64_t x) {
    auto e = losses_.upper_bound(x);
    if (e == losses_.begin()) return;
    --e;
    if (e->first < x && x < e->second.last) {
      losses_.emplace(x, e->second);
      e->second.last = x;
    }
  };
  const auto count = [&](Lost& l) {
    if (l.who.size() < kLossesKept && std::find(l.who.begin(), l.who.end(), who) == l.who.end()) l.who.push_back(who);
  };
  for (const Range& r : it->second) {
    split(r.first);
    split(r.last);
    uint64_t at = r.first;
    for (auto e = losses_.lower_bound(r.first); at < r.last;) {
      if (e == losses_.end() || e->first >= r.last) {  // no entry from `at` on: a new one to r.last
        losses_.emplace(at, Lost{r.last, {who}});
        break;
      }
      if (e->first > at) losses_.emplace(at, Lost{e->first, {who}});  // the gap before it
      count(e->second);
      at = e->second.last;
      ++e;
    }
  }
  abandon(node);
}

std::optional<Range> Ledger::poisoned(uint32_t times) const {
  std::optional<Range> out;
  for (const auto& [first, e] : losses_) {
    if (e.who.size() >= times && (!out || out->last == first)) {
      if (!out) out = Range{first, first};
      out->last = e.last;
    } else if (out) {
      break;
    }
  }
  return out;
}

uint64_t Ledger::revoke(uint32_t node) {
  abandon(node);
  auto it = done_.find(node);
  if (it == done_.end()) return 0;
  uint64_t n = 0;
  for (const Range& r : it->second) {
    free_.push_back(r);
    n += r.size();
  }
  done_.erase(it);
  done_count_ -= n;
  free_ = merged(std::move(free_));
  return n;
}

Ledger Ledger::from_record(uint64_t bundles, const std::map<uint32_t, std::vector<Range>>& done) {
  Ledger l(bundles);
  std::vector<Range> all;
  for (const auto& [node, ranges] : done)
    for (const Range& r : ranges) {
      if (r.last <= r.first || r.last > bundles) fail("ledger: node {} range [{}, {}) outside 0..{}", node, r.first, r.last, bundles);
      all.push_back(r);
      l.done_[node].push_back(r);
      l.done_count_ += r.size();
    }
  std::sort(all.begin(), all.end(), [](const Range& a, const Range& b) { return a.first < b.first; });
  l.free_.clear();
  uint64_t at = 0;
  for (const Range& r : all) {
    if (r.first < at) fail("ledger: bundle {} is done twice", r.first);
    if (r.first > at) l.free_.push_back({at, r.first});
    at = r.last;
  }
  if (at < bundles) l.free_.push_back({at, bundles});
  return l;
}

std::vector<Range> Ledger::done_by(uint32_t node) const {
  auto it = done_.find(node);
  return it == done_.end() ? std::vector<Range>{} : merged(it->second);
}

uint64_t Ledger::outstanding(uint32_t node) const {
  auto it = granted_.find(node);
  uint64_t n = 0;
  if (it != granted_.end())
    for (const Range& r : it->second) n += r.size();
  return n;
}

std::vector<uint32_t> chunk_starts(uint32_t patches, uint32_t chunks) {
  if (chunks == 0 || chunks > std::max<uint32_t>(patches, 1))
    fail("chunks: {} chunks for {} patches (need 1 .. patches)", chunks, patches);
  std::vector<uint32_t> starts(chunks + 1);
  for (uint32_t c = 0; c <= chunks; ++c)
    starts[c] = static_cast<uint32_t>(static_cast<uint64_t>(patches) * c / chunks);
  return starts;
}

std::vector<uint32_t> exchange_chunks(uint32_t exchange, double fraction, uint32_t chunks) {
  if (!(fraction > 0.0 && fraction <= 1.0)) fail("--exchange-fraction {} outside (0, 1]", fraction);
  uint32_t n = std::min<uint32_t>(chunks, static_cast<uint32_t>(std::ceil(fraction * chunks - 1e-9)));
  n = std::max<uint32_t>(n, 1);
  std::vector<uint32_t> out(n);
  for (uint32_t i = 0; i < n; ++i)
    out[i] = static_cast<uint32_t>((static_cast<uint64_t>(exchange) * n + i) % chunks);
  return out;
}

Aggregate::Aggregate(std::vector<uint32_t> starts, uint32_t nodes) : starts_(std::move(starts)) {
  SIRAD_CHECK(starts_.size() >= 2, "aggregate: no chunks");
  for (uint32_t p = 0; p < nodes; ++p) add_node();
}

void Aggregate::add_node() { state_.emplace_back(); }  // nothing held: its parts are allocated at its first set

Aggregate::Part Aggregate::zeros(uint32_t chunk) const {
  return {std::vector<double>(3 * static_cast<std::size_t>(chunk_size(chunk)), 0.0), 0};
}

const Aggregate::Held* Aggregate::held(uint32_t node, uint32_t chunk) const {
  const std::vector<Held>& parts = state_.at(node);
  return parts.empty() || parts.at(chunk).mean.empty() ? nullptr : &parts[chunk];
}

bool Aggregate::holds_nothing(uint32_t node) const {
  for (const Held& p : state_.at(node))
    if (p.count > 0) return false;
  return true;
}

Aggregate::Part Aggregate::state(uint32_t node, uint32_t chunk) const {
  SIRAD_CHECK(chunk < chunks(), "aggregate: no chunk {}", chunk);
  Part out = zeros(chunk);
  if (const Held* h = held(node, chunk)) {
    for (std::size_t i = 0; i < out.sum.size(); ++i) out.sum[i] = h->sum(i);
    out.count = h->count;
  }
  return out;
}

void Aggregate::check(uint32_t node, uint32_t chunk, const std::vector<double>& sum, uint64_t count) const {
  SIRAD_CHECK(node < nodes(), "aggregate: no node {}", node);
  if (chunk >= chunks()) fail("node {}: no chunk {} (the run has {})", node, chunk, chunks());
  if (sum.size() != 3 * static_cast<std::size_t>(chunk_size(chunk)))
    fail("node {}: chunk {} has {} values, expected {}", node, chunk, sum.size(), 3 * chunk_size(chunk));
  const uint64_t before = state_[node].empty() ? 0 : state_[node][chunk].count;
  if (count < before) fail("node {}: count of chunk {} went back from {} to {}", node, chunk, before, count);
  // Sums are signed: the transport's control variate (solver/solver.cpp) makes a single
  // estimate of a nearly dark patch negative at times. What no node can send: a non-finite
  // value, one beyond count x the largest float (every estimate is made from floats), or
  // anything but zeros with a count of 0.
  const double limit = static_cast<double>(count) * static_cast<double>(std::numeric_limits<float>::max());
  for (std::size_t i = 0; i < sum.size(); ++i)
    if (!std::isfinite(sum[i]) || std::fabs(sum[i]) > limit)
      fail("node {}: chunk {} value {} is {} ({} bundles)", node, chunk, i, sum[i], count);
}

void Aggregate::set(uint32_t node, uint32_t chunk, std::vector<double> sum, uint64_t count) {
  check(node, chunk, sum, count);
  if (state_[node].empty()) state_[node].resize(chunks());
  Held& part = state_[node][chunk];
  part.mean.resize(sum.size());
  const double inverse = count > 0 ? 1.0 / static_cast<double>(count) : 0.0;
  for (std::size_t i = 0; i < sum.size(); ++i) part.mean[i] = static_cast<float>(sum[i] * inverse);
  part.count = count;
}

void Aggregate::clear(uint32_t node) {
  SIRAD_CHECK(node < nodes(), "aggregate: no node {}", node);
  state_[node] = {};  // back to zeros, its memory freed
}

Aggregate::Part Aggregate::others(uint32_t node, uint32_t chunk, Topology topology) const {
  if (topology == Topology::ring) return nodes() > 1 ? state((node + 1) % nodes(), chunk) : zeros(chunk);
  Part out = zeros(chunk);
  for (uint32_t p = 0; p < nodes(); ++p) {
    const Held* s = p == node ? nullptr : held(p, chunk);
    if (!s) continue;
    for (std::size_t i = 0; i < s->mean.size(); ++i) out.sum[i] += s->sum(i);
    out.count += s->count;
  }
  return out;
}

uint64_t Aggregate::count(uint32_t chunk) const {
  uint64_t n = 0;
  for (const auto& parts : state_)
    if (!parts.empty()) n += parts[chunk].count;
  return n;
}

std::vector<double> Aggregate::estimate(uint32_t chunk) const {
  std::vector<double> out(3 * static_cast<std::size_t>(chunk_size(chunk)), 0.0);
  uint64_t n = count(chunk);
  if (n == 0) return out;
  for (uint32_t p = 0; p < nodes(); ++p)
    if (const Held* part = held(p, chunk))
      for (std::size_t i = 0; i < out.size(); ++i) out[i] += part->sum(i);
  for (double& v : out) v /= static_cast<double>(n);
  return out;
}

double Aggregate::spread_error(const std::vector<double>& weight) const {
  double var_sum = 0, mean_sum = 0;
  bool any = false;
  for (uint32_t c = 0; c < chunks(); ++c) {
    uint32_t holders = 0;
    for (uint32_t p = 0; p < nodes(); ++p) holders += held(p, c) && held(p, c)->count > 0;
    if (holders < 2) continue;
    any = true;
    std::vector<double> g = estimate(c);
    double total = static_cast<double>(count(c));
    for (uint32_t j = 0; j < chunk_size(c); ++j) {
      double w = weight.at(starts_[c] + j);
      if (w <= 0) continue;
      for (int k = 0; k < 3; ++k) {
        std::size_t i = 3 * static_cast<std::size_t>(j) + static_cast<std::size_t>(k);
        double ss = 0;
        for (uint32_t p = 0; p < nodes(); ++p) {
          const Held* part = held(p, c);
          if (!part || part->count == 0) continue;
          double d = static_cast<double>(part->mean[i]) - g[i];
          ss += static_cast<double>(part->count) * d * d;
        }
        var_sum += w * ss / (holders - 1) / total / 3;
        mean_sum += w * g[i] * g[i] / 3;
      }
    }
  }
  return any && mean_sum > 0 ? std::sqrt(var_sum / mean_sum) : -1.0;
}

double Aggregate::combined_error(const std::vector<double>& error, const std::vector<uint64_t>& bundles,
                                 const std::vector<double>& weight) const {
  SIRAD_CHECK(error.size() == nodes() && bundles.size() == nodes(), "combined error: {} estimates for {} nodes", error.size(), nodes());
  double acc = 0, total_w = 0;
  for (uint32_t c = 0; c < chunks(); ++c) {
    double w = 0;
    for (uint32_t j = 0; j < chunk_size(c); ++j) w += std::max(0.0, weight.at(starts_[c] + j));
    if (w <= 0) continue;
    const double m_total = static_cast<double>(count(c));
    if (m_total <= 0) return -1.0;
    double v = 0;
    for (uint32_t p = 0; p < nodes(); ++p) {
      const Held* part = held(p, c);
      const double m = part ? static_cast<double>(part->count) : 0.0;
      if (m == 0) continue;
      if (!(error[p] > 0)) return -1.0;
      const double n = std::max(m, static_cast<double>(bundles[p]));
      v += m * n * error[p] * error[p];
    }
    acc += w * v / (m_total * m_total);
    total_w += w;
  }
  return total_w > 0 ? std::sqrt(acc / total_w) : -1.0;
}

}  // namespace sirad::cluster
