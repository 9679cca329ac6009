// sirad: what an honest node's state of a chunk can be: see plausibility.h.
#include "cluster/plausibility.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <glm/common.hpp>

#include "util/error.h"

namespace sirad::cluster {

namespace {

constexpr const char* kChannel[3] = {"red", "green", "blue"};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double upper_median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

ChunkBounds chunk_bounds(const PatchMesh& mesh, const std::vector<uint32_t>& starts) {
  if (starts.size() < 2 || starts.back() != mesh.size()) fail("chunk bounds: chunks do not cover the {} patches", mesh.size());
  // Per channel: the largest emission and reflectance, and the bound on any patch's radiosity.
  glm::dvec3 e_max(0.0), rho_max(0.0);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    e_max = glm::max(e_max, glm::dvec3(mesh.emission(j)));
    rho_max = glm::max(rho_max, glm::dvec3(mesh.reflectance(j)));
  }
  const glm::dvec3 bg(mesh.background);
  glm::dvec3 gathered;  // the most any patch can gather: max(Bmax, Bg)
  for (int k = 0; k < 3; ++k)
    gathered[k] = rho_max[k] >= 1.0 ? std::numeric_limits<double>::infinity()
                                    : std::max({e_max[k] / (1.0 - rho_max[k]), e_max[k] + rho_max[k] * bg[k], bg[k]});
  ChunkBounds b;
  b.weight.resize(mesh.size());
  for (std::size_t c = 0; c + 1 < starts.size(); ++c) {
    double area = 0;
    for (uint32_t j = starts[c]; j < starts[c + 1]; ++j) area += mesh.area[j];
    glm::dvec3 low(0.0), high(0.0);
    for (uint32_t j = starts[c]; j < starts[c + 1]; ++j) {
      const double a = mesh.area[j] / area;
      b.weight[j] = a;
      const glm::dvec3 e(mesh.emission(j)), rho(mesh.reflectance(j));
      low += a * e;
      for (int k = 0; k < 3; ++k) high[k] += a * (e[k] + (rho[k] > 0 ? rho[k] * gathered[k] : 0.0));
    }
    b.low.push_back(low);
    b.high.push_back(high);
  }
  return b;
}

uint64_t chain_memory(const PatchMesh& mesh, double shots_per_bundle) {
  float rho_max = 0.0f;
  for (const auto& m : mesh.materials) rho_max = std::max({rho_max, m.reflectance.x, m.reflectance.y, m.reflectance.z});
  double g = 1.0;
  if (rho_max >= 1.0f) g = 1024;
  else if (rho_max > 0.0f) g = std::ceil(std::log(1e-2) / std::log(static_cast<double>(rho_max)));
  if (shots_per_bundle > 0 && shots_per_bundle < 1) g = std::max(g, std::ceil(4.0 / shots_per_bundle - 1e-9));
  return static_cast<uint64_t>(std::clamp(g, 1.0, 1024.0));
}

Plausibility::Plausibility(std::vector<uint32_t> starts, ChunkBounds bounds, uint64_t batch_bundles, bool compare)
    : starts_(std::move(starts)), bounds_(std::move(bounds)), batch_bundles_(std::max<uint64_t>(1, batch_bundles)),
      compare_(compare) {
  if (starts_.size() < 2) fail("plausibility: no chunks");
  if (bounds_.weight.empty()) {  // every patch of a chunk weighs the same
    bounds_.weight.resize(starts_.back());
    for (std::size_t c = 0; c + 1 < starts_.size(); ++c)
      for (uint32_t j = starts_[c]; j < starts_[c + 1]; ++j) bounds_.weight[j] = 1.0 / (starts_[c + 1] - starts_[c]);
  }
  if (bounds_.weight.size() != starts_.back() || (!bounds_.low.empty() && bounds_.low.size() + 1 != starts_.size()))
    fail("plausibility: bounds for another mesh");
}

Plausibility::Observation Plausibility::observe(uint32_t chunk, const std::vector<double>& sum, uint64_t count) const {
  Observation o;
  o.count = count;
  const uint32_t first = starts_.at(chunk);
  for (uint32_t j = first; j < starts_.at(chunk + 1); ++j) {
    const std::size_t i = 3 * static_cast<std::size_t>(j - first);
    o.s += bounds_.weight[j] * glm::dvec3(sum.at(i), sum.at(i + 1), sum.at(i + 2));
  }
  return o;
}

void Plausibility::add_node() {
  stats_.emplace_back();
  excluded_.push_back(false);
}

const Plausibility::Stats* Plausibility::stats(uint32_t n, uint32_t chunk) const {
  if (n >= stats_.size() || stats_[n].empty()) return nullptr;
  return &stats_[n].at(chunk);
}

Plausibility::Stats Plausibility::Stats::closed() const {
  Stats s = *this;
  if (s.count > s.batched) {
    s.batches.push_back({s.count - s.batched, s.s - s.batched_s});
    s.batched = s.count;
    s.batched_s = s.s;
  }
  return s;
}

glm::dvec3 Plausibility::jackknife_variance(const std::vector<Batch>& batches) {
  const std::size_t k = batches.size();
  if (k < 2) return glm::dvec3(0.0);
  uint64_t m = 0;
  glm::dvec3 s(0.0);
  for (const Batch& b : batches) m += b.n, s += b.s;
  std::vector<glm::dvec3> out(k);  // y without batch i
  glm::dvec3 mean(0.0);
  for (std::size_t i = 0; i < k; ++i) {
    out[i] = (s - batches[i].s) / static_cast<double>(m - batches[i].n);
    mean += out[i] / static_cast<double>(k);
  }
  glm::dvec3 ss(0.0);
  for (const glm::dvec3& v : out) ss += (v - mean) * (v - mean);
  return ss * (static_cast<double>(k - 1) / static_cast<double>(k));
}

Plausibility::Stats Plausibility::advanced(const Stats& before, const Observation& o) const {
  Stats s = before;
  if (s.length == 0) s.length = batch_bundles_;
  s.s = o.s;
  s.count = o.count;
  // The bundles since the last whole batch become one once there are `length` of them.
  if (s.count - s.batched >= s.length) s = s.closed();
  if (s.batches.size() > kSlots) {  // neighbours merge, batches get twice as long
    std::vector<Batch> merged;
    for (std::size_t i = 0; i < s.batches.size(); i += 2) {
      Batch b = s.batches[i];
      if (i + 1 < s.batches.size()) b.n += s.batches[i + 1].n, b.s += s.batches[i + 1].s;
      merged.push_back(b);
    }
    s.batches = std::move(merged);
    s.length *= 2;
  }
  return s;
}

namespace {

std::string sigmas(double off, double se) {
  return se > 0 ? fmt::format("{:.3g} standard errors", off / se) : std::string("standard errors of 0 (no spread at all)");
}

}  // namespace

Plausibility::Verdict Plausibility::assess(uint32_t n, uint32_t chunk, const Observation& o) const {
  Verdict v;
  if (o.count == 0) return v;
  // Scores `off` against its allowance; the first over 1 gives the verdict its reason.
  auto score = [&v](double off, double se, double floor, auto&& why) {
    const double s = off <= 0 ? 0.0 : off / (kZ * se + floor);
    if (s > 1 && v.why.empty()) v.why = why();
    v.score = std::max(v.score, std::isfinite(s) ? s : std::numeric_limits<double>::max());
  };
  const Stats* before = stats(n, chunk);
  const Stats next = advanced(before ? *before : Stats{}, o);
  const Stats p = next.closed();  // every bundle of the state, in y and in its variance
  const double m = static_cast<double>(p.count);
  const glm::dvec3 y = p.s / m, own = jackknife_variance(p.batches);
  if (!bounds_.low.empty() && next.batches.size() >= kMinBatches)
    for (int k = 0; k < 3; ++k) {
      const double se = std::sqrt(own[k]), high = bounds_.high[chunk][k], low = bounds_.low[chunk][k];
      score(y[k] - high, se, kFloor * high, [&] {
        return fmt::format("chunk {} ({}): mean radiosity {:.6g} is above what the scene allows, {:.6g}, by {} of its own",
                           chunk, kChannel[k], y[k], high, sigmas(y[k] - high, se));
      });
      score(low - y[k], se, kFloor * low, [&] {
        return fmt::format("chunk {} ({}): mean radiosity {:.6g} is below its emission, {:.6g}, by {} of its own", chunk,
                           kChannel[k], y[k], low, sigmas(low - y[k], se));
      });
    }
  if (!compare_ || next.batches.size() < kMinBatches) return v;
  // The references: other nodes with enough whole batches of this chunk.
  std::vector<Stats> refs;
  for (uint32_t q = 0; q < stats_.size(); ++q)
    if (q != n && !excluded_[q])
      if (const Stats* s = stats(q, chunk); s && s->batches.size() >= kMinBatches) refs.push_back(s->closed());
  if (refs.size() < 2) return v;
  double m_min = std::numeric_limits<double>::infinity();
  for (const Stats& s : refs) m_min = std::min(m_min, static_cast<double>(s.count));
  std::vector<glm::dvec3> ref_variance;
  for (const Stats& s : refs) ref_variance.push_back(jackknife_variance(s.batches) * static_cast<double>(s.count));  // per bundle
  for (int k = 0; k < 3; ++k) {
    std::vector<double> ys{y[k]}, vs;
    for (std::size_t i = 0; i < refs.size(); ++i) {
      ys.push_back(refs[i].s[k] / static_cast<double>(refs[i].count));
      vs.push_back(ref_variance[i][k]);
    }
    const double med = median(ys), v_ref = upper_median(vs);
    const double se = std::sqrt(std::max(v_ref / m, own[k]) + v_ref / m_min), off = std::fabs(y[k] - med);
    score(off, se, kFloor * std::fabs(med), [&] {
      return fmt::format("chunk {} ({}): mean radiosity {:.6g} is {} from {:.6g}, the median of {} nodes", chunk, kChannel[k],
                         y[k], sigmas(off, se), med, refs.size() + 1);
    });
  }
  return v;
}

void Plausibility::take(uint32_t n, uint32_t chunk, const Observation& o) {
  std::vector<Stats>& node = stats_.at(n);
  if (node.empty()) node.resize(starts_.size() - 1);
  node.at(chunk) = advanced(node[chunk], o);
}

void Plausibility::clear(uint32_t n) {
  stats_.at(n) = {};
  excluded_.at(n) = true;
}

void Plausibility::forget(uint32_t n) {
  stats_.at(n) = {};
  excluded_.at(n) = false;
}

uint32_t Plausibility::batches(uint32_t n, uint32_t chunk) const {
  const Stats* s = stats(n, chunk);
  return s ? static_cast<uint32_t>(s->batches.size()) : 0;
}

}  // namespace sirad::cluster
