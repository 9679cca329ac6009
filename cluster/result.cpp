// sirad: a cluster run's report lines (see result.h).
#include "cluster/result.h"

#include "cluster/policy.h"

#include <algorithm>

#include <string_view>

#include <fmt/format.h>

namespace sirad::cluster {

RunOutcome outcome_of(const RunResult& r) {
  return {r.bundles, r.grid, static_cast<uint32_t>(r.nodes.size()), r.exchange_every, r.fraction, r.ended_by, r.seconds, r.crossings};
}

RunResult policy_result(const Policy& p, int grid) {
  RunResult r;
  r.radiosity = p.radiosity();
  r.exchanges = p.exchanges();
  r.grid = grid;
  r.bundles = p.ledger().done_count();
  r.ended_by = p.ended_by().empty() ? "budget" : p.ended_by();
  r.bundles_lost = p.ledger().poisoned(Policy::kMaxBundleLosses);
  r.error_estimate = p.error_estimate();
  r.exchange_every = p.exchange_every();
  r.fraction = p.fraction();
  r.exchange_why = p.exchange_why();
  return r;
}

Status policy_status(const Policy& p, const RunSettings& settings, bool last) {
  Status s;
  s.settings = settings_text(settings);
  s.target_error = settings.target_error;
  if (last) {
    s.ended_by = p.ended_by().empty() ? "budget" : p.ended_by();
    if (s.ended_by == "budget" && settings.target_error > 0) s.ended_by = "bundle cap reached short of the target error";
  }
  s.bundles_done = p.ledger().done_count();
  s.bundles = settings.bundles;
  s.patches = p.starts().empty() ? 0 : p.starts().back();  // the starts end with the patch count
  s.error_estimate = p.error_estimate();
  s.exchanges = p.exchanges();
  s.exchange_every = p.exchange_every() == kExchangeAuto ? 0 : p.exchange_every();
  s.exchange_fraction = p.fraction();
  s.mode = settings.mode == Mode::sync ? "sync" : "async";
  s.topology = settings.topology == Topology::star ? "star" : "ring";
  for (uint32_t i = 0; i < p.nodes(); ++i) {
    const NodeState& ns = p.node(i);
    Status::Node n;
    n.state = ns.state();
    n.why = ns.why;
    n.suspicion = ns.suspicion;
    n.bundles = ns.bundles;
    n.exchanges = ns.exchanges;
    s.nodes.push_back(std::move(n));
  }
  return s;
}

std::string traffic_line(const RunResult& r) {
  uint64_t e = std::max<uint64_t>(r.exchanges, 1);
  return fmt::format("exchange traffic: {} exchanges, {} B up, {} B down ({} B up, {} B down per exchange); final states {} B",
                     r.exchanges, r.exchange_bytes_in, r.exchange_bytes_out, r.exchange_bytes_in / e,
                     r.exchange_bytes_out / e, r.final_bytes);
}

std::string ledger_csv(const RunResult& r) {
  std::string out = "node,name,first,last\n";
  for (const LedgerEntry& e : r.ledger) {
    // A node's name as a CSV field: quoted, quotes doubled, and one that a spreadsheet would
    // take for a formula (starting with = + - @, a tab or a carriage return) led by a ', which
    // spreadsheets show as text (OWASP's rule against CSV injection).
    std::string name = e.name;
    for (std::size_t at = name.find('"'); at != std::string::npos; at = name.find('"', at + 2)) name.insert(at, 1, '"');
    if (!name.empty() && std::string_view("=+-@\t\r").find(name.front()) != std::string_view::npos) name.insert(0, 1, '\'');
    out += fmt::format("{},\"{}\",{},{}\n", e.node, name, e.range.first, e.range.last);
  }
  return out;
}

std::string node_lines(const RunResult& r) {
  std::string out;
  for (const auto& n : r.nodes)
    out += fmt::format("node {}: {} bundles, {} exchanges, busy {:.2f} s, idle {:.2f} s{}{}\n", n.name, n.bundles,
                       n.exchanges, n.busy_s, n.idle_s, n.tiles > 0 ? fmt::format(", {} tiles", n.tiles) : "",
                       !n.quarantined.empty() ? ", quarantined: " + n.quarantined
                       : n.before_resume      ? ", before the resume"
                       : n.dead               ? ", dead"
                                              : "");
  return out;
}

std::string summary_line(std::size_t patches, uint64_t bundles, int grid, uint32_t nodes, double seconds, uint64_t crossings,
                         const std::string& extra) {
  const double s = std::max(seconds, 1e-9);
  const double rate = static_cast<double>(bundles) / s;
  return fmt::format("patches {}, bundles {}, grid {}{}, {:.2f} s, {:.1f} bundles/s, {:.3g} patch-bundles/s, {:.3g} line crossings/s{}",
                     patches, bundles, grid, nodes > 0 ? fmt::format(", nodes {}", nodes) : "", seconds, rate,
                     rate * static_cast<double>(patches), static_cast<double>(crossings) / s, extra);
}

std::string cluster_summary(const RunResult& r, std::size_t patches, double seconds) {
  // A resumed run: the counts and rates of this run; what came before said apart.
  uint32_t nodes = 0, before = 0;
  for (const NodeReport& n : r.nodes) (n.before_resume ? before : nodes) += 1;
  const std::string resumed =
      r.bundles_before > 0 || before > 0
          ? fmt::format("; before the resume: {} bundles by {} nodes ({} in all)", r.bundles_before, before, r.bundles)
          : "";
  const std::string image = r.image ? fmt::format("image: {} tiles in {:.2f} s{}\n", r.image_tiles, r.image_seconds,
                                                   r.tiles_here > 0 ? fmt::format(", {} rendered by the coordinator", r.tiles_here) : "")
                                    : "";
  return node_lines(r) + traffic_line(r) + "\n" + image +
         summary_line(patches, r.bundles - std::min(r.bundles, r.bundles_before), r.grid, nodes, seconds,
                      r.crossings - std::min(r.crossings, r.crossings_before), resumed) +
         "\n";
}

}  // namespace sirad::cluster
