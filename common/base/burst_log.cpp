#include "common/base/burst_log.hpp"

#include <utility>

namespace fogmap {
namespace {

std::string secondsText(std::int64_t ns) {
  const std::int64_t tenths = (ns + 50'000'000) / 100'000'000;
  return std::to_string(tenths / 10) + "." + std::to_string(tenths % 10) + " s";
}

}  // namespace

BurstLog::BurstLog(std::string prefix, Sink sink, NowNs now, std::chrono::milliseconds quiet,
                   std::chrono::milliseconds interval)
    : prefix_(std::move(prefix)),
      sink_(std::move(sink)),
      now_(std::move(now)),
      quiet_ns_(std::chrono::duration_cast<std::chrono::nanoseconds>(quiet).count()),
      interval_ns_(std::chrono::duration_cast<std::chrono::nanoseconds>(interval).count()) {}

void BurstLog::write(const std::string& line) {
  ++lines_;
  if (sink_) sink_(prefix_ + line);
}

void BurstLog::summarise(const std::string& reason, Burst& burst, std::int64_t now_ns) {
  if (burst.unreported > 0) {
    write(reason + ": " + std::to_string(burst.unreported) + " more in the last " +
          secondsText(now_ns - burst.summary_ns) + " (latest: " + burst.latest + ")");
  }
  burst.unreported = 0;
  burst.summary_ns = now_ns;
}

void BurstLog::note(const std::string& reason, const std::string& detail) {
  std::lock_guard lock(mutex_);
  const std::int64_t now_ns = now_();
  auto it = bursts_.find(reason);
  if (it != bursts_.end() && now_ns - it->second.last_ns >= quiet_ns_) {
    // The old burst went quiet: its summary, then this event opens a new one.
    summarise(reason, it->second, it->second.last_ns);
    bursts_.erase(it);
    it = bursts_.end();
  }
  if (it == bursts_.end()) {
    bursts_.emplace(reason, Burst{now_ns, now_ns, 0, detail});
    write(reason + ": " + detail + " (more of this reason are counted and summarised)");
    return;
  }
  Burst& burst = it->second;
  burst.last_ns = now_ns;
  burst.latest = detail;
  ++burst.unreported;
  if (now_ns - burst.summary_ns >= interval_ns_) summarise(reason, burst, now_ns);
}

void BurstLog::flush(bool all) {
  std::lock_guard lock(mutex_);
  const std::int64_t now_ns = now_();
  for (auto it = bursts_.begin(); it != bursts_.end();) {
    if (all || now_ns - it->second.last_ns >= quiet_ns_) {
      summarise(it->first, it->second, all ? now_ns : it->second.last_ns);
      it = bursts_.erase(it);
    } else {
      ++it;
    }
  }
}

std::uint64_t BurstLog::linesWritten() const {
  std::lock_guard lock(mutex_);
  return lines_;
}

}  // namespace fogmap
