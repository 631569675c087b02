#pragma once
// Replays a sensor's recorded scans (SensorConfig.source): a directory of scans in name order, or
// one file, optionally looped and limited to a number of frames, cut to a virtual LiDAR's sector
// when the sensor is split. Pacing is the caller's: next() returns at once.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "common/cloud.hpp"
#include "common/status.hpp"
#include "common/topology.hpp"

namespace fogmap {

struct ScanFrame {
  std::uint64_t sequence = 0;            // 0, 1, 2, ... over emitted frames, across loops
  std::filesystem::path file;            // the scan it was read from
  Cloud points;                          // in the sensor frame (the sector's frame when split)
  std::size_t dropped_non_finite = 0;    // points the reader dropped (NaN or infinite coordinates)
};

class ScanSource {
 public:
  // Lists the scans of `sensor.source`: the *.bin, *.pcd.bin and *.pcd files of a directory
  // sorted by name, or the one file. Errors when the source does not exist, a single file has an
  // unsupported name, or a directory holds no scans.
  static Expected<ScanSource> open(const SensorConfig& sensor);

  // True once `frames` frames were emitted, or after the last scan when not looping, or after a
  // whole pass over the scans emitted nothing (looping could never succeed).
  bool done() const;

  // Reads the next scan. A file that cannot be read yields an Error naming it and is skipped: the
  // following call continues with the next file. Must not be called when done().
  Expected<ScanFrame> next();

  // Reads the scan of time epoch `epoch` (the scan epoch mod the number of scans), so that every
  // sensor replaying one recording shows the same scan in the same epoch; sequence = epoch.
  Expected<ScanFrame> at(std::uint64_t epoch);
  const std::vector<std::filesystem::path>& files() const { return files_; }
  std::uint64_t emitted() const { return emitted_; }

 private:
  ScanSource(SensorConfig sensor, std::vector<std::filesystem::path> files);
  Expected<ScanFrame> read(const std::filesystem::path& file, std::uint64_t sequence);

  SensorConfig sensor_;
  std::vector<std::filesystem::path> files_;
  std::size_t position_ = 0;          // index into files_ of the next scan to read
  std::uint64_t emitted_ = 0;         // frames emitted so far (= the next sequence number)
  std::size_t failures_in_a_row_ = 0;  // consecutive unreadable files
  bool exhausted_ = false;            // passed the last scan without looping
};

}  // namespace fogmap
