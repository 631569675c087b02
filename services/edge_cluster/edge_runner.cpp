#include "services/edge_cluster/edge_runner.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

namespace fogmap {
namespace {

constexpr std::uint64_t kStatusEveryEpochs = 10;
// Errors can name a frame number, so distinct messages are unbounded; past this many the rest
// are counted, not logged.
constexpr std::size_t kMaxLoggedErrors = 256;

std::int64_t sensorPeriodNs(double rate_hz) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) return 1;  // validated upstream; never divide by zero
  return std::max<std::int64_t>(1, std::llround(1e9 / rate_hz));
}

std::size_t uploadsOf(const EdgeOutput& output) { return (output.map ? 1U : 0U) + output.chunks.size(); }

void setDroppedUploads(EdgeOutput& output, std::uint64_t dropped) {
  if (output.map) output.map->header.dropped_uploads = dropped;
  for (PointChunk& chunk : output.chunks) chunk.header.dropped_uploads = dropped;
}

}  // namespace

std::uint64_t scanNumberAt(const EpochSchedule& schedule, double sensor_rate_hz, std::uint64_t epoch) {
  return static_cast<std::uint64_t>(schedule.startNs(epoch) / sensorPeriodNs(sensor_rate_hz));
}

EdgeRunner::EdgeRunner(EdgeNode edge, ScanProvider& scans, EpochSchedule schedule, double sensor_rate_hz,
                       EdgeRunnerHooks hooks)
    : edge_(std::move(edge)),
      scans_(scans),
      schedule_(schedule),
      sensor_rate_hz_(sensor_rate_hz),
      hooks_(std::move(hooks)) {}

std::uint64_t EdgeRunner::scanNumberAt(std::uint64_t epoch) const {
  return fogmap::scanNumberAt(schedule_, sensor_rate_hz_, epoch);
}

EdgeStep EdgeRunner::step() {
  if (!next_epoch_) next_epoch_ = schedule_.epochAt(hooks_.now()) + 1;
  const std::uint64_t epoch = *next_epoch_;
  const std::uint64_t scan_number = scanNumberAt(epoch);
  const bool fresh = !current_ || current_->scan_number != scan_number;
  // Checked before waiting: a finished recording should not cost another period.
  if (fresh && scans_.done()) return EdgeStep::kDone;
  if (!hooks_.wait_until(schedule_.startNs(epoch))) return EdgeStep::kStopped;

  if (fresh) {
    current_ = ScanResult{scan_number, readAndProcess(scan_number, epoch)};
  } else {
    restamp(epoch);
  }

  const bool failed = !current_->output.ok();
  EdgeOutput failed_output;
  if (failed) failed_output = edge_.failedFrame(epoch);
  EdgeOutput& output = failed ? failed_output : *current_->output;
  setDroppedUploads(output, hooks_.dropped_uploads ? hooks_.dropped_uploads() : 0);

  hooks_.ship(output);
  ++stats_.epochs_shipped;
  if (failed) ++stats_.failed_frames;
  if (hooks_.observer != nullptr) {
    hooks_.observer->shipped(output);
    if (failed) hooks_.observer->failedFrame();
  }
  if ((stats_.epochs_shipped - 1) % kStatusEveryEpochs == 0) logStatus(epoch, output, failed, !fresh);

  // After a stall (a frame longer than a period, a slow disk) go on with the current epoch, late,
  // rather than ship the missed ones in a burst: their data would be stale and the parent has
  // closed them or is about to.
  const std::uint64_t now_epoch = schedule_.epochAt(hooks_.now());
  if (now_epoch > epoch + 1) {
    const std::uint64_t skipped = now_epoch - epoch - 1;
    if (stats_.skipped_epochs == 0 && hooks_.log) {
      hooks_.log("stalled: epoch " + std::to_string(epoch) + " ended in epoch " + std::to_string(now_epoch) +
                 "; skipping " + std::to_string(skipped) +
                 " epoch(s) and going on with the current one (later stalls are counted in the status lines)");
    }
    stats_.skipped_epochs += skipped;
  }
  next_epoch_ = std::max(epoch + 1, now_epoch);
  return EdgeStep::kShipped;
}

EdgeStep EdgeRunner::run() {
  for (;;) {
    const EdgeStep result = step();
    if (result != EdgeStep::kShipped) return result;
  }
}

Expected<EdgeOutput> EdgeRunner::readAndProcess(std::uint64_t scan_number, std::uint64_t epoch) {
  Expected<ScanFrame> frame = scans_.at(scan_number);
  // The sensor timestamp is when the scan is in memory, as a live sensor delivers it: reading and
  // cutting a recorded scan into a virtual LiDAR is the replay's cost, not the pipeline's.
  const std::int64_t sensor_time_ns = hooks_.now();
  if (!frame) {
    if (hooks_.observer != nullptr) hooks_.observer->malformed("scan");
    logFailure(epoch, scan_number, frame.error().message);
    return frame.error();
  }
  // The reader dropped the non-finite points of a file; a provider that passes some on (a live
  // sensor) has them dropped here. Either way each is counted, and the scan goes on without them.
  const std::size_t non_finite =
      frame->dropped_non_finite + std::erase_if(frame->points, [](const Point& p) { return !isFinitePoint(p); });
  if (non_finite > 0) {
    stats_.dropped_non_finite_points += non_finite;
    if (hooks_.observer != nullptr) {
      hooks_.observer->malformed("non_finite_points");
      hooks_.observer->droppedPoints("non_finite", non_finite);
    }
  }
  if (frame->trailing_zero_bytes > 0) {
    ++stats_.padded_scans;
    if (hooks_.observer != nullptr) hooks_.observer->paddedScan();
    logOnce(padded_files_, frame->file.string(),
            frame->file.string() + ": " + std::to_string(frame->trailing_zero_bytes) +
                " zero byte(s) after the declared points; accepted (warned once per file)");
  }

  Expected<EdgeOutput> output = edge_.processFrame(frame->points, epoch, sensor_time_ns);
  if (!output) {
    if (hooks_.observer != nullptr) hooks_.observer->malformed("frame");
    Error error = output.error();
    error.message = frame->file.string() + ": " + error.message;
    logFailure(epoch, scan_number, error.message);
    return error;
  }
  ++stats_.scans_processed;
  if (hooks_.observer != nullptr) hooks_.observer->scanProcessed(*output);
  return output;
}

void EdgeRunner::restamp(std::uint64_t epoch) {
  if (!current_->output) return;  // a failed frame is built for each epoch
  EdgeOutput& output = *current_->output;
  // Ellipsoid ids are (node, epoch, index): one node's ids share node and epoch, so changing the
  // epoch keeps the map's canonical order.
  if (output.map) {
    output.map->header.epoch = epoch;
    for (MapObject& object : output.map->map.objects) {
      for (Ellipsoid& ellipsoid : object.ellipsoids) ellipsoid.id.frame = epoch;
    }
  }
  for (PointChunk& chunk : output.chunks) chunk.header.epoch = epoch;
  // Centroids go to the tracker once per scan: a re-used scan shows nothing that moved since.
  output.centroids.reset();
}

void EdgeRunner::logFailure(std::uint64_t epoch, std::uint64_t scan_number, const std::string& message) {
  logOnce(logged_errors_, message,
          "failed frame (epoch " + std::to_string(epoch) + ", scan " + std::to_string(scan_number) +
              "), sent empty and flagged failed: " + message + " (each distinct error is logged once)");
}

void EdgeRunner::logOnce(std::set<std::string>& seen, const std::string& key, const std::string& line) {
  if (!hooks_.log || seen.count(key) > 0) return;
  if (seen.size() >= kMaxLoggedErrors) return;
  seen.insert(key);
  hooks_.log(line);
  if (seen.size() == kMaxLoggedErrors) {
    hooks_.log(std::to_string(kMaxLoggedErrors) + " distinct messages logged; further ones are only counted");
  }
}

void EdgeRunner::logStatus(std::uint64_t epoch, const EdgeOutput& output, bool failed, bool reused) {
  if (!hooks_.log) return;
  std::ostringstream line;
  line << "epoch " << epoch << ", scan " << current_->scan_number << ": ";
  if (failed) {
    line << "failed frame, sent empty (" << stats_.failed_frames << " failed so far)";
  } else {
    line << output.points_in << " points in, " << output.points_out << " after pre-processing ("
         << output.preprocess_seconds * 1e3 << " ms), " << output.clusters << " clusters ("
         << output.clustering_seconds * 1e3 << " ms)";
    if (output.displacement_seconds) {
      line << ", " << (output.centroids ? output.centroids->centroids.size() : 0U) << " displacement centroids ("
           << *output.displacement_seconds * 1e3 << " ms)";
    }
    line << (reused ? ", re-used from the previous epoch" : "");
  }
  line << ", " << uploadsOf(output) << " upload(s)";
  if (stats_.skipped_epochs > 0) line << ", " << stats_.skipped_epochs << " epoch(s) skipped after stalls";
  if (hooks_.link_status) line << "; " << hooks_.link_status();
  hooks_.log(line.str());
}

}  // namespace fogmap
