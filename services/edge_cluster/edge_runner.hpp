#pragma once
// The edge's replay loop (docs/design.md "Edge"): one output every epoch of the CLUSTER period
// (common/base/epochs.hpp), whatever the sensor's rate. Epoch k is captured at its start, k P; it shows
// the sensor's most recent scan at that instant, scan number floor(k P / sensor period); a scan
// that cannot be read or processed is shipped as a failed frame (EdgeNode::failedFrame) instead
// of leaving the parent to wait out its deadline. Points with a NaN or infinite coordinate never
// reach processing: the reader drops those of a file, the runner any other, and every one is
// counted. Time comes in through a clock and a wait
// function, so tests drive it by hand; the output goes to a sink in domain types (the service
// converts and sends); messages go to a log sink. No gRPC, no printing.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>

#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/base/status.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap {

// What the runner reports for metrics; every method does nothing unless overridden.
class EdgeObserver {
 public:
  virtual ~EdgeObserver() = default;
  // A scan was read and processed (once per scan, not again when its result is re-used; with
  // displacement, the output holds the detector's time and centroids).
  virtual void scanProcessed(const EdgeOutput& /*output*/) {}
  // An epoch's output was handed to the sink (failed frames included).
  virtual void shipped(const EdgeOutput& /*output*/) {}
  // An epoch was shipped as a failed frame.
  virtual void failedFrame() {}
  // A rejected input: "scan" (unreadable, too large), "frame" (processing failed),
  // "non_finite_points" (a scan that had some; once per scan).
  virtual void malformed(const std::string& /*what*/) {}
  // `points` points of a scan were dropped before processing, for `reason` ("non_finite": a NaN
  // or infinite coordinate); once per scan that had any.
  virtual void droppedPoints(const std::string& /*reason*/, std::size_t /*points*/) {}
  // A scan was read with zero padding after its declared points (accepted).
  virtual void paddedScan() {}
};

// The scan number a sensor of `sensor_rate_hz` shows in `epoch`: floor(startNs(epoch) / sensor
// period). The runner and anything that recomputes an edge's output (fault tests) use this one.
std::uint64_t scanNumberAt(const EpochSchedule& schedule, double sensor_rate_hz, std::uint64_t epoch);

// Blocks until the clock reaches `until_ns` (at once when it has); false when a stop was
// requested, in which case the runner ships nothing more.
using WaitUntil = std::function<bool(std::int64_t until_ns)>;

struct EdgeRunnerHooks {
  NowNs now;                                        // unix ns (systemNowNs in the service)
  WaitUntil wait_until;
  std::function<void(const EdgeOutput&)> ship;      // every epoch's output, in epoch order
  std::function<std::uint64_t()> dropped_uploads;   // the link's dropped-upload total; empty: 0
  std::function<void(const std::string&)> log;      // one line, no prefix; empty: silent
  std::function<std::string()> link_status;         // appended to status lines; may be empty
  EdgeObserver* observer = nullptr;                 // may be null
};

struct EdgeRunnerStats {
  std::uint64_t epochs_shipped = 0;   // outputs handed to the sink, failed frames included
  std::uint64_t scans_processed = 0;  // scans read and processed (a re-used result counts once)
  std::uint64_t failed_frames = 0;    // epochs shipped as failed frames
  std::uint64_t skipped_epochs = 0;   // epochs passed over after stalls
  std::uint64_t padded_scans = 0;     // scans read with zero padding
  std::uint64_t dropped_non_finite_points = 0;  // points with a NaN or infinite coordinate
};

enum class EdgeStep {
  kShipped,  // one epoch's output went to the sink
  kStopped,  // the wait function reported a stop request; nothing was shipped
  kDone,     // the next epoch needs a new scan and the provider has none
};

class EdgeRunner {
 public:
  // `scans` must outlive the runner. `sensor_rate_hz` (the sensor's scan rate, positive and
  // finite; topology validation ensures it) only chooses which scan is current at an instant.
  EdgeRunner(EdgeNode edge, ScanProvider& scans, EpochSchedule schedule, double sensor_rate_hz,
             EdgeRunnerHooks hooks);

  // Ships one epoch: the first call chooses the epoch after the current one; each call waits for
  // its epoch's start, reads and processes the scan current then (or re-uses the previous
  // result, re-stamped with this epoch's header and ellipsoid ids, when the scan number did not
  // change; a re-used output carries no displacement centroids: they are shipped once per scan),
  // ships it, and chooses the next epoch: the following one, or after a stall the current one
  // (epochs in between are skipped, never shipped in a burst).
  EdgeStep step();
  // step() until it stops or the scans are done; returns the last step (kStopped or kDone).
  EdgeStep run();

  // The scan number shown in `epoch`: floor(startNs(epoch) / sensor period).
  std::uint64_t scanNumberAt(std::uint64_t epoch) const;
  // The epoch the next step() ships; empty before the first step.
  std::optional<std::uint64_t> nextEpoch() const { return next_epoch_; }
  const EdgeRunnerStats& stats() const { return stats_; }

 private:
  // The output of the current scan (or why there is none), stamped for the last epoch shipped.
  struct ScanResult {
    std::uint64_t scan_number = 0;
    Expected<EdgeOutput> output;
  };

  Expected<EdgeOutput> readAndProcess(std::uint64_t scan_number, std::uint64_t epoch);
  void restamp(std::uint64_t epoch);
  void logFailure(std::uint64_t epoch, std::uint64_t scan_number, const std::string& message);
  void logOnce(std::set<std::string>& seen, const std::string& key, const std::string& line);
  void logStatus(std::uint64_t epoch, const EdgeOutput& output, bool failed, bool reused);

  EdgeNode edge_;
  ScanProvider& scans_;
  EpochSchedule schedule_;
  double sensor_rate_hz_;
  EdgeRunnerHooks hooks_;

  std::optional<std::uint64_t> next_epoch_;
  std::optional<ScanResult> current_;
  EdgeRunnerStats stats_;
  std::set<std::string> logged_errors_;  // each distinct error is logged once, counted every time
  std::set<std::string> padded_files_;   // each padded file is warned about once
};

}  // namespace fogmap
