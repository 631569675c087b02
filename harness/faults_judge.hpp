#pragma once
// The fault harness's judgement (harness/faults.hpp): from what a run observed, the report's
// figures (sent vs applied, liveness, latency, memory, the fault's notice, rejoin and recovery
// times) and its checks against the protocol's bounds. Pure: no processes, no clock, no files.
#include "common/base/epochs.hpp"
#include "common/config/topology.hpp"
#include "harness/faults.hpp"
#include "harness/faults_observe.hpp"

namespace fogmap::harness {

// Scheduling slack allowed on top of the protocol's bound when a figure is checked against it.
inline constexpr double kFaultSlackMs = 100.0;
// The stall and crash bounds: the root marks a subtree missing, and the children of a stalled
// parent give their stream up, within 3 s; a restarted edge is merged again within 2 s of being up;
// the root is whole again within 5 s of the heal and stays so for 10 epochs at least.
inline constexpr double kChildNoticeBoundMs = 3000.0;
inline constexpr double kRejoinBoundMs = 2000.0;
inline constexpr double kRecoveryBoundMs = 5000.0;
// Soak: the largest RSS growth of a process after the warm-up.
inline constexpr std::int64_t kMaxRssGrowthKib = 64 * 1024;

// The report of a run of `plan` on `topology` (`schedule` its epochs) that observed `seen`: every
// figure of FaultReport but `fault` (the plan's describeFault), and the checks.
// - A map is lost when an edge's parent acknowledged it (applied or late) for an epoch judged and
//   no publication of that epoch names the edge among its contributing nodes; lost in the fault
//   when the edge lies below an aggregator killed or stopped at T and healed at H, for epochs from
//   the one of T - (deadline x its levels + period) to the one of H + 2 s + the admission window.
// - The window of liveness: from the first epoch judged whose first publication came during the
//   load, to the last epoch that ended before the load did.
// - An epoch is whole when its latest publication holds every map acknowledged for it and equals
//   the specification; recovery is the first epoch after the heal from which every epoch is whole,
//   counted from the heal to that epoch's emission (its start plus the root's deadline).
FaultReport judgeFaults(const TopologyConfig& topology, const FaultPlan& plan, const EpochSchedule& schedule,
                        const FaultObservation& seen);

}  // namespace fogmap::harness
