#include "harness/faults_judge.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/base/clock.hpp"
#include "harness/cluster_run.hpp"

namespace fogmap::harness {
namespace {

// Maps acknowledged in the subtree of a killed or stopped aggregator, for these epochs, count as
// lost in the fault: by it before it was killed, or by the aggregators below it, whose uploads
// waited in their links until too old to be admitted.
struct FaultWindow {
  std::string node;
  std::set<std::uint32_t> sensors;
  std::uint64_t first_epoch = 0;
  std::uint64_t last_epoch = std::numeric_limits<std::uint64_t>::max();  // until healed
};

// The faults as they happened: when each node went down, the edges' restarts, the last heal and
// the fault windows of the aggregators.
struct Timeline {
  std::vector<std::pair<std::string, std::int64_t>> downs;  // node, unix ns: for missing notices
  std::vector<Restart> edge_restarts;                        // for rejoin times
  std::optional<std::int64_t> heal_ns;                       // continued, or an aggregator up again
  std::vector<FaultWindow> windows;
};

Timeline timeline(const TopologyConfig& topology, const EpochSchedule& schedule, const FaultObservation& seen) {
  Timeline t;
  // An aggregator healed at H: the maps below it wait out the link's backoff cap (2 s) and are
  // admitted within the admission window after that.
  const auto settle_ns = static_cast<std::int64_t>((2000.0 + topology.admission.window_periods * topology.period_ms) * 1e6);
  const auto heal = [&](const std::string& node, std::int64_t at_ns) {
    t.heal_ns = at_ns;
    for (FaultWindow& w : t.windows) {
      if (w.node == node && w.last_epoch == std::numeric_limits<std::uint64_t>::max()) {
        w.last_epoch = schedule.epochAt(at_ns + settle_ns);
      }
    }
  };
  for (const FaultEvent& e : seen.events) {
    const NodeConfig* n = topology.find(e.node);
    if (n == nullptr) continue;
    if (e.what == "kill" || e.what == "stop" || e.what == "drop") {
      t.downs.emplace_back(e.node, e.at_ns);
      if (n->role == Role::kAggregator) {
        // Maps it acknowledged for epochs it had not emitted yet die with it (kill).
        const auto emit_ns = static_cast<std::int64_t>(
            (topology.deadline_ms * topology.aggregatorLevels(e.node) + topology.period_ms) * 1e6);
        const auto below = topology.sensorsBelow(e.node);
        t.windows.push_back({e.node, {below.begin(), below.end()}, schedule.epochAt(e.at_ns - emit_ns)});
      }
    } else if (e.what == "continue" || e.what == "restore") {
      heal(e.node, e.at_ns);
    } else if (e.what == "restart") {
      const auto r = std::find_if(seen.restarts.begin(), seen.restarts.end(),
                                  [&](const Restart& x) { return x.node == e.node && x.commanded_ns == e.at_ns; });
      if (r == seen.restarts.end()) continue;
      // Healed once the process is up again: its start-up is not the cluster's recovery.
      if (n->role == Role::kEdge) t.edge_restarts.push_back(*r);
      if (n->role == Role::kAggregator) heal(e.node, r->ready_ns);
    }
  }
  return t;
}

}  // namespace

FaultReport judgeFaults(const TopologyConfig& topology, const FaultPlan& plan, const EpochSchedule& schedule,
                        const FaultObservation& seen) {
  const NodeConfig* root = topology.root();
  const std::vector<std::uint32_t> sensors = root ? topology.sensorsBelow(root->name) : std::vector<std::uint32_t>{};
  const bool with_oracle = plan.check_oracle && topology.mode == Mode::kMadc;

  FaultReport report;
  report.topology = topology.name;
  report.scenario = scenarioName(plan.scenario);
  report.seed = plan.seed;
  report.duration_s = static_cast<double>(plan.duration.count()) / 1000.0;
  report.edges = static_cast<int>(sensors.size());
  report.period_ms = topology.period_ms;
  report.root_deadline_ms = root ? topology.deadline_ms * topology.aggregatorLevels(root->name) : 0.0;
  report.events = seen.events;
  report.crashed = seen.crashed;
  report.memory = seen.memory;
  for (const ProcessMemory& m : seen.memory) {
    report.max_rss_growth_kib = std::max(report.max_rss_growth_kib, static_cast<double>(m.rss_end_kib - m.rss_after_warmup_kib));
  }
  report.observer_drops = seen.observer_drops;
  report.root_caught_up = seen.root_caught_up;
  report.root_longest_poll_gap_ms = seen.root_longest_poll_gap_ms;
  report.duplicates_recognised = seen.duplicates_recognised;
  report.child_notice_ms = seen.child_notice_ms;
  report.phases = seen.phases;
  const Timeline faults = timeline(topology, schedule, seen);

  // Sent vs applied.
  const std::vector<Publication>& pubs = seen.publications;
  std::map<std::uint64_t, std::set<std::uint32_t>> applied;
  std::map<std::uint64_t, std::set<std::uint32_t>> acknowledged;  // what the edges' parents acknowledged
  for (const Publication& p : pubs) applied[p.epoch].insert(p.contributing.begin(), p.contributing.end());
  for (const EdgeJournal& journal : seen.journals) {
    for (const JournalEntry& j : journal.entries) {
      if (j.kind != "map" || j.epoch < seen.judged_from) continue;
      ++report.maps_sent;
      if (j.outcome == Outcome::kRefused) ++report.maps_refused;
      if (j.outcome == Outcome::kUnsettled) ++report.maps_unsettled;
      if (j.outcome != Outcome::kApplied && j.outcome != Outcome::kLate) continue;
      ++report.maps_acknowledged;
      acknowledged[j.epoch].insert(journal.node);
      if (applied[j.epoch].contains(journal.node)) continue;
      const bool in_fault = std::any_of(faults.windows.begin(), faults.windows.end(), [&](const FaultWindow& w) {
        return w.sensors.contains(journal.node) && j.epoch >= w.first_epoch && j.epoch <= w.last_epoch;
      });
      ++(in_fault ? report.maps_lost_in_fault : report.maps_lost);
      if (!in_fault && report.lost_examples.size() < 10) {
        report.lost_examples.push_back(journal.name + " epoch +" +
                                       std::to_string(static_cast<long long>(j.epoch) -
                                                      static_cast<long long>(schedule.epochAt(seen.start_ns))) +
                                       " (" + outcomeName(j.outcome) + ")");
      }
    }
  }
  report.applied_twice = seen.applied_twice;
  report.publications_checked = seen.checked;
  report.publications_mismatched = seen.mismatched;

  // Liveness and latency over the loaded window.
  const std::uint64_t last_loaded = schedule.epochAt(seen.end_ns) - 1;
  std::optional<std::uint64_t> first_published;
  std::vector<std::int64_t> first_times;
  std::vector<double> e2e;
  std::optional<std::uint64_t> newest_first;  // the newest epoch whose first publication came
  for (const Publication& p : pubs) {
    report.publications += 1;
    report.late_publications += p.late ? 1 : 0;
    if (p.revision == 0) {
      if (newest_first && p.epoch <= *newest_first) ++report.out_of_order;
      newest_first = std::max(newest_first.value_or(p.epoch), p.epoch);
    }
    // Only epochs that began once the subscription delivered: a late first publication of an
    // older epoch would otherwise pull the window back over epochs published before it.
    if (p.revision != 0 || p.epoch > last_loaded || p.epoch < seen.judged_from || p.published_ns < seen.start_ns) continue;
    first_published = std::min(first_published.value_or(p.epoch), p.epoch);
    first_times.push_back(p.published_ns);
    if (p.contributing.size() == sensors.size()) e2e.push_back(nsToMs(p.published_ns - p.sensor_ns));
  }
  if (first_published) {
    report.epochs_in_window = last_loaded - *first_published + 1;
    for (std::uint64_t e = *first_published; e <= last_loaded; ++e) {
      if (applied.contains(e)) continue;
      ++report.epochs_unpublished;
      if (report.unpublished_examples.size() < 10) report.unpublished_examples.push_back(e - *first_published);
    }
  }
  std::sort(first_times.begin(), first_times.end());
  for (std::size_t i = 1; i < first_times.size(); ++i) {
    report.max_silence_ms = std::max(report.max_silence_ms, nsToMs(first_times[i] - first_times[i - 1]));
  }
  report.e2e_p50_ms = percentile(e2e, 0.5);
  report.e2e_p99_ms = percentile(e2e, 0.99);

  // Fault figures.
  for (const auto& [name, at] : faults.downs) {
    const auto below = topology.sensorsBelow(name);
    std::optional<double> notice;
    for (const Publication& p : pubs) {
      if (p.revision != 0 || p.published_ns < at) continue;
      if (std::any_of(below.begin(), below.end(), [&](std::uint32_t s) { return p.missing.contains(s); })) {
        notice = std::min(notice.value_or(1e18), nsToMs(p.published_ns - at));
      }
    }
    report.missing_notice_ms.push_back(notice.value_or(-1.0));
  }
  for (const Restart& restart : faults.edge_restarts) {
    const std::uint32_t id = topology.find(restart.node)->id;
    const std::int64_t at = restart.ready_ns;
    std::optional<double> rejoin;
    for (const Publication& p : pubs) {
      if (p.published_ns >= at && p.contributing.contains(id)) rejoin = std::min(rejoin.value_or(1e18), nsToMs(p.published_ns - at));
    }
    report.rejoin_ms.push_back(rejoin.value_or(-1.0));
    report.restart_startup_ms.push_back(nsToMs(restart.ready_ns - restart.commanded_ns));
  }
  if (faults.heal_ns) {
    const std::int64_t heal_ns = *faults.heal_ns;
    const auto& verdicts = seen.verdicts;
    // An epoch is whole when its latest publication holds every map the edges' parents
    // acknowledged for it and equals the specification: what the fault-free cluster would have
    // published from what the edges sent (an edge behind its schedule skips epochs; that is not
    // the fault's doing, and each skip is counted by the edge).
    const auto whole = [&](std::uint64_t e) {
      const auto v = verdicts.find(e);
      if (v == verdicts.end() || !v->second.equal) return false;
      const auto& sent = acknowledged[e];
      return std::includes(v->second.contributing.begin(), v->second.contributing.end(), sent.begin(), sent.end());
    };
    std::optional<std::uint64_t> recovered;  // first epoch from which every loaded epoch is whole
    for (std::uint64_t e = schedule.epochAt(heal_ns); e <= last_loaded && report.after_heal.size() < 40; ++e) {
      const auto v = verdicts.find(e);
      report.after_heal.push_back(v == verdicts.end() ? "-" : std::string(whole(e) ? "w" : "i") + (v->second.equal ? "" : "!"));
    }
    for (std::uint64_t e = last_loaded; e >= schedule.epochAt(heal_ns) && e > 0; --e) {
      if (!whole(e)) break;
      recovered = e;
    }
    if (recovered) {
      report.recovery_ms = nsToMs(schedule.startNs(*recovered) - heal_ns) + report.root_deadline_ms;
      report.epochs_after_recovery = last_loaded - *recovered + 1;
    }
  }

  // The checks.
  auto check = [&](const std::string& name, bool ok, const std::string& detail) { report.checks.push_back({name, ok, detail}); };
  const std::vector<std::string>& problems = seen.problems;
  check("every global map the root published was readable", std::none_of(problems.begin(), problems.end(), [](const std::string& p) {
          return p.rfind("the root published an unreadable map", 0) == 0;
        }), problems.empty() ? "" : problems.front());
  check("no process died unless killed", report.crashed.empty(),
        report.crashed.empty() ? "" : "died: " + report.crashed.front());
  // Every epoch, in order: a stall of the root's own makes it publish the epochs it missed late
  // (flagged), never leave them out; an epoch complete early waits for the older ones.
  std::string unpublished = std::to_string(report.epochs_unpublished) + " of " + std::to_string(report.epochs_in_window) +
                            " unpublished";
  for (std::uint64_t e : report.unpublished_examples) unpublished += " +" + std::to_string(e);
  unpublished += "; the root dropped " + std::to_string(report.observer_drops) + " of the harness's subscription, caught up " +
                 std::to_string(report.root_caught_up) + " after stalls (longest poll gap " +
                 std::to_string(report.root_longest_poll_gap_ms) + " ms)";
  check("the root published every epoch", report.epochs_in_window > 0 && report.epochs_unpublished == 0, unpublished);
  check("the root published the epochs in order", report.out_of_order == 0,
        std::to_string(report.out_of_order) + " first publications of an epoch older than one published before");
  // The schedule's own bound on a silence: an epoch is published once complete, at the earliest
  // when it begins, and at the latest at its deadline, a period plus the root's deadline after the
  // one before began (slack for the poll and a busy machine on top, as for the missing notice).
  const double silence_bound = topology.period_ms + report.root_deadline_ms + kFaultSlackMs;
  check("the root was never silent for longer than a period and its deadline", report.max_silence_ms <= silence_bound,
        "longest silence " + std::to_string(report.max_silence_ms) + " ms, bound " + std::to_string(silence_bound) + " ms");
  check("no acknowledged map lost", report.maps_lost == 0, std::to_string(report.maps_lost) + " lost");
  check("no map applied twice", report.applied_twice == 0, std::to_string(report.applied_twice) + " duplicates");
  if (with_oracle) {
    check("every global map equals the specification", report.publications_checked > 0 && report.publications_mismatched == 0,
          std::to_string(report.publications_mismatched) + " of " + std::to_string(report.publications_checked) +
              (problems.empty() ? std::string() : "; " + problems.front()));
  }
  std::ostringstream bound;
  const double missing_bound = silence_bound;
  bound << "bound " << missing_bound << " ms";
  switch (plan.scenario) {
    case FaultScenario::kSoak:
      check("memory bounded after the warm-up", seen.warm_sampled && report.max_rss_growth_kib <= static_cast<double>(kMaxRssGrowthKib),
            std::to_string(static_cast<long>(report.max_rss_growth_kib)) + " KiB largest growth");
      break;
    case FaultScenario::kEdgeCrash:
      for (double n : report.missing_notice_ms) check("a killed edge is marked missing in time", n >= 0 && n <= missing_bound, std::to_string(n) + " ms, " + bound.str());
      for (double r : report.rejoin_ms) check("a restarted edge is merged again within 2 s of being up", r >= 0 && r <= kRejoinBoundMs, std::to_string(r) + " ms");
      break;
    case FaultScenario::kAggregatorCrash:
    case FaultScenario::kStall:
      for (double n : report.missing_notice_ms) check("the root marks the subtree missing within 3 s", n >= 0 && n <= kChildNoticeBoundMs, std::to_string(n) + " ms");
      if (plan.scenario == FaultScenario::kStall) {
        check("the children notice the stall within 3 s", report.child_notice_ms && *report.child_notice_ms <= kChildNoticeBoundMs,
              report.child_notice_ms ? std::to_string(*report.child_notice_ms) + " ms" : "never");
      }
      check("the root converges to the fault-free maps after recovery",
            report.recovery_ms && *report.recovery_ms <= kRecoveryBoundMs && report.epochs_after_recovery >= 10,
            report.recovery_ms ? std::to_string(*report.recovery_ms) + " ms, then " + std::to_string(report.epochs_after_recovery) + " epochs equal"
                               : "never");
      break;
  }
  return report;
}

}  // namespace fogmap::harness
