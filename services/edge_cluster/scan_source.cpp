#include "services/edge_cluster/scan_source.hpp"

#include <algorithm>
#include <string>
#include <system_error>
#include <utility>

#include "common/io/cloud_io.hpp"
#include "common/perception/virtual_lidar.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;

bool isScanFile(const fs::path& path) { return cloudFormatFromPath(path).ok(); }

// cloud_io's errors name the file already; make sure of it, since the operator acts on the name.
Error namingFile(Error error, const fs::path& file) {
  if (error.message.find(file.string()) == std::string::npos) error.message = file.string() + ": " + error.message;
  return error;
}

}  // namespace

ScanSource::ScanSource(SensorConfig sensor, ReadLimits limits, std::size_t kept_bytes, std::vector<fs::path> files)
    : sensor_(std::move(sensor)),
      limits_(limits),
      files_(std::move(files)),
      kept_budget_bytes_(kept_bytes),
      kept_(files_.size()) {}

Expected<ScanSource> ScanSource::open(const SensorConfig& sensor, ReadLimits limits) {
  return open(sensor, limits, kDefaultKeptBytes);
}

Expected<ScanSource> ScanSource::open(const SensorConfig& sensor, ReadLimits limits, std::size_t kept_bytes) {
  const fs::path& source = sensor.source;
  std::error_code ec;
  const fs::file_status status = fs::status(source, ec);
  if (status.type() == fs::file_type::not_found) return notFound(source.string() + ": no such scan file or directory");
  if (ec) return ioError(source.string() + ": cannot access the scan source: " + ec.message());

  std::vector<fs::path> files;
  if (fs::is_directory(status)) {
    fs::directory_iterator it(source, ec);
    if (ec) return ioError(source.string() + ": cannot list the scan directory: " + ec.message());
    for (const fs::directory_entry& entry : it) {
      // Other files (calib.txt, timestamps) may sit next to the scans; they are not scans.
      std::error_code entry_ec;
      if (entry.is_regular_file(entry_ec) && isScanFile(entry.path())) files.push_back(entry.path());
    }
    if (files.empty()) {
      return invalidArgument(source.string() + ": the directory holds no scans (*.bin, *.pcd.bin or *.pcd files)");
    }
    std::sort(files.begin(), files.end(),
              [](const fs::path& a, const fs::path& b) { return a.filename().string() < b.filename().string(); });
  } else {
    Expected<CloudFormat> format = cloudFormatFromPath(source);
    if (!format) return format.error();
    files.push_back(source);
  }
  return ScanSource(sensor, limits, kept_bytes, std::move(files));
}

std::string ScanSource::describe() const {
  return std::to_string(files_.size()) + " scan(s) from " + sensor_.source.string();
}

bool ScanSource::done() const {
  if (sensor_.frames && emitted_ >= *sensor_.frames) return true;
  return exhausted_ || failures_in_a_row_ >= files_.size();
}

Expected<ScanFrame> ScanSource::next() {
  if (done()) return Error{ErrorCode::kInternal, "ScanSource::next called after the source is done"};

  const std::size_t file = position_;
  ++position_;
  if (position_ == files_.size()) {
    position_ = 0;
    exhausted_ = !sensor_.loop;
  }

  return read(file, emitted_);
}

Expected<ScanFrame> ScanSource::at(std::uint64_t n) {
  if (done()) return Error{ErrorCode::kInternal, "ScanSource::at called after the source is done"};
  // Without looping each scan plays once: the source ends after as many reads as files, readable
  // or not (an unreadable file is still its turn in the recording).
  if (!sensor_.loop && ++reads_by_number_ >= files_.size()) exhausted_ = true;
  return read(static_cast<std::size_t>(n % files_.size()), n);
}

Expected<ScanFrame> ScanSource::read(std::size_t file_index, std::uint64_t sequence) {
  const fs::path& file = files_[file_index];
  std::optional<Kept>& kept = kept_[file_index];
  ScanFrame frame;
  if (kept) {
    frame.points = kept->points;
    frame.dropped_non_finite = kept->dropped_non_finite;
    frame.trailing_zero_bytes = kept->trailing_zero_bytes;
  } else {
    Expected<LoadedCloud> loaded = readCloud(file, limits_);
    ++file_reads_;
    if (!loaded) {
      ++failures_in_a_row_;
      return namingFile(loaded.error(), file);
    }
    frame.points = sensor_.split ? sectorView(loaded->points, *sensor_.split) : std::move(loaded->points);
    frame.dropped_non_finite = loaded->dropped_non_finite;
    frame.trailing_zero_bytes = loaded->trailing_zero_bytes;
    const std::size_t bytes = frame.points.size() * sizeof(Point);
    if (kept_budget_bytes_ > 0 && bytes <= kept_budget_bytes_ - kept_bytes_) {  // kept_bytes_ <= the budget
      kept_bytes_ += bytes;
      kept = Kept{frame.points, frame.dropped_non_finite, frame.trailing_zero_bytes};
    }
  }
  failures_in_a_row_ = 0;
  ++emitted_;
  frame.sequence = sequence;
  frame.file = file;
  return frame;
}

}  // namespace fogmap
