// The fault harness's report (harness/faults.hpp): toJson and summary.
#include <iomanip>
#include <sstream>

#include "harness/faults.hpp"
#include "harness/report_text.hpp"

namespace fogmap::harness {
namespace {

Json numbers(const std::vector<double>& values) {
  Json list = Json::array();
  for (const double v : values) list.push_back(jsonNumber(v));
  return list;
}

Json optionalNumber(const std::optional<double>& v) { return v ? jsonNumber(*v) : Json(nullptr); }

}  // namespace

std::string toJson(const FaultReport& r) {
  Json j;
  j["topology"] = r.topology;
  j["scenario"] = r.scenario;
  j["fault"] = r.fault;
  j["seed"] = r.seed;
  j["duration_s"] = jsonNumber(r.duration_s);
  j["edges"] = r.edges;
  j["period_ms"] = jsonNumber(r.period_ms);
  j["root_deadline_ms"] = jsonNumber(r.root_deadline_ms);
  j["epochs_in_window"] = r.epochs_in_window;
  j["epochs_unpublished"] = r.epochs_unpublished;
  j["max_silence_ms"] = jsonNumber(r.max_silence_ms);
  j["publications"] = r.publications;
  j["late_publications"] = r.late_publications;
  j["out_of_order"] = r.out_of_order;
  j["root_caught_up"] = r.root_caught_up;
  j["root_longest_poll_gap_ms"] = jsonNumber(r.root_longest_poll_gap_ms);
  j["maps_sent"] = r.maps_sent;
  j["maps_acknowledged"] = r.maps_acknowledged;
  j["maps_refused"] = r.maps_refused;
  j["maps_unsettled"] = r.maps_unsettled;
  j["maps_lost"] = r.maps_lost;
  j["maps_lost_in_fault"] = r.maps_lost_in_fault;
  j["applied_twice"] = r.applied_twice;
  j["duplicates_recognised"] = r.duplicates_recognised;
  j["observer_drops"] = r.observer_drops;
  j["publications_checked"] = r.publications_checked;
  j["publications_mismatched"] = r.publications_mismatched;
  j["e2e_p50_ms"] = jsonNumber(r.e2e_p50_ms);
  j["e2e_p99_ms"] = jsonNumber(r.e2e_p99_ms);
  j["max_rss_growth_kib"] = jsonNumber(r.max_rss_growth_kib);
  j["missing_notice_ms"] = numbers(r.missing_notice_ms);
  j["rejoin_ms"] = numbers(r.rejoin_ms);
  j["restart_startup_ms"] = numbers(r.restart_startup_ms);
  j["recovery_ms"] = optionalNumber(r.recovery_ms);
  j["child_notice_ms"] = optionalNumber(r.child_notice_ms);
  j["epochs_after_recovery"] = r.epochs_after_recovery;
  j["memory"] = Json::array();
  for (const ProcessMemory& m : r.memory) {
    j["memory"].push_back({{"node", m.node}, {"rss_after_warmup_kib", m.rss_after_warmup_kib}, {"rss_end_kib", m.rss_end_kib}});
  }
  j["events"] = Json::array();
  for (const FaultEvent& e : r.events) j["events"].push_back({{"what", e.what}, {"node", e.node}, {"at_ns", e.at_ns}});
  j["crashed"] = r.crashed;
  j["checks"] = Json::array();
  for (const Check& c : r.checks) j["checks"].push_back({{"name", c.name}, {"passed", c.passed}, {"detail", c.detail}});
  j["passed"] = r.passed();
  return jsonText(j);
}

std::string summary(const FaultReport& r) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(1);
  o << "faults " << r.scenario << " on " << r.topology << " (" << r.edges << " edges, period " << r.period_ms
    << " ms, seed " << r.seed << ", " << r.duration_s << " s)\n";
  if (!r.fault.empty()) o << "  fault: " << r.fault << "\n";
  for (const FaultEvent& e : r.events) o << "  event: " << e.what << " " << e.node << "\n";
  o << "  root: " << r.epochs_in_window - r.epochs_unpublished << " of " << r.epochs_in_window
    << " epochs published, longest silence " << r.max_silence_ms << " ms, " << r.late_publications << " late of "
    << r.publications << " publications, " << r.out_of_order << " out of order; " << r.root_caught_up
    << " caught up after stalls of the root (longest poll gap " << r.root_longest_poll_gap_ms << " ms)\n";
  if (!r.unpublished_examples.empty()) {
    o << "  never published (epochs after the first):";
    for (std::uint64_t e : r.unpublished_examples) o << " +" << e;
    o << "\n";
  }
  o << "  maps: " << r.maps_sent << " sent, " << r.maps_acknowledged << " acknowledged, " << r.maps_refused
    << " refused, " << r.maps_unsettled << " unsettled; " << r.maps_lost << " lost, " << r.maps_lost_in_fault
    << " lost in the faulty subtree during the fault; " << r.applied_twice << " applied twice (" << r.duplicates_recognised
    << " re-sent copies recognised); the root dropped " << r.observer_drops << " global maps of the harness's subscription\n";
  if (!r.lost_examples.empty()) {
    o << "  lost:";
    for (const std::string& l : r.lost_examples) o << " " << l << ";";
    o << "\n";
  }
  o << "  oracle: " << r.publications_mismatched << " of " << r.publications_checked
    << " global maps differ from the specification\n";
  o << "  end-to-end: p50 " << r.e2e_p50_ms << " ms, p99 " << r.e2e_p99_ms << " ms; largest RSS growth after warm-up "
    << r.max_rss_growth_kib / 1024.0 << " MiB\n";
  for (double n : r.missing_notice_ms) o << "  marked missing after " << n << " ms\n";
  for (std::size_t i = 0; i < r.rejoin_ms.size(); ++i) {
    o << "  restarted edge up after " << (i < r.restart_startup_ms.size() ? r.restart_startup_ms[i] : -1.0)
      << " ms, merged again " << r.rejoin_ms[i] << " ms after that\n";
  }
  if (r.child_notice_ms) o << "  children noticed the stall after " << *r.child_notice_ms << " ms\n";
  if (!r.after_heal.empty()) {
    o << "  epochs after the heal (w whole, i an acknowledged map missing, - unpublished, ! differs):";
    for (const std::string& e : r.after_heal) o << " " << e;
    o << "\n";
  }
  if (r.recovery_ms) {
    o << "  recovered " << *r.recovery_ms << " ms after the heal; " << r.epochs_after_recovery
      << " epochs after it, each holding every acknowledged map and equal to the specification\n";
  }
  o << "  phases:";
  for (const auto& [name, seconds] : r.phases) o << " " << name << " " << seconds << " s";
  o << "\n";
  for (const Check& c : r.checks) o << "  [" << (c.passed ? "ok" : "FAIL") << "] " << c.name << (c.detail.empty() ? "" : ": " + c.detail) << "\n";
  o << (r.passed() ? "PASSED\n" : "FAILED\n");
  return o.str();
}

}  // namespace fogmap::harness
