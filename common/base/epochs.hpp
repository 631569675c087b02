#pragma once
// Epochs (DESIGN.md 2.2, docs/design.md "Epochs"): epoch k is the window [k P, (k + 1) P) of unix
// time for the cluster period P (topology period_ms), the same for every sensor whatever its
// rate. Deadlines are absolute: an aggregator with L levels of aggregators below it (L = 1 over
// edges) emits epoch k at k P + L D (D = topology deadline_ms). A child at level L - 1 emits at
// k P + (L - 1) D at the latest, so its map reaches the parent a whole D before the parent's
// deadline: no on-time map is dropped in a tree of any depth as long as one hop (processing and
// transport) takes less than D.
#include <cstdint>

#include "common/base/status.hpp"

namespace fogmap {

class EpochSchedule {
 public:
  // Errors unless period_ms and deadline_ms are finite, positive, and at most one hour.
  static Expected<EpochSchedule> create(double period_ms, double deadline_ms);

  std::int64_t periodNs() const { return period_ns_; }
  std::int64_t deadlineNs() const { return deadline_ns_; }

  // The epoch whose window holds `now_ns` (0 for times before the unix epoch).
  std::uint64_t epochAt(std::int64_t now_ns) const;
  // Start of epoch k in unix ns; saturates at INT64_MAX for epochs beyond representable time.
  std::int64_t startNs(std::uint64_t epoch) const;
  // When an aggregator with `levels` levels of aggregators below it emits epoch k (saturating).
  std::int64_t deadlineNs(std::uint64_t epoch, int levels) const;

 private:
  EpochSchedule(std::int64_t period_ns, std::int64_t deadline_ns) : period_ns_(period_ns), deadline_ns_(deadline_ns) {}
  std::int64_t period_ns_;
  std::int64_t deadline_ns_;
};

}  // namespace fogmap
