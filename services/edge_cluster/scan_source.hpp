#pragma once
// Replays a sensor's recorded scans (SensorConfig.source): a directory of scans in name order, or
// one file, optionally looped and limited to a number of frames, cut to a virtual LiDAR's sector
// when the sensor is split. Files above the size bound are refused unread. Pacing is the caller's:
// next() and at() return at once. A scan read once is kept (cut to the sector) while the kept
// scans stay under a memory budget, so a looped recording is parsed once, not at every frame: a
// recording is replayed as it was when first read, and a file that failed is read again.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/geometry/cloud.hpp"
#include "common/io/cloud_io.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap {

struct ScanFrame {
  std::uint64_t sequence = 0;            // 0, 1, 2, ... over emitted frames, across loops
  std::filesystem::path file;            // the scan it was read from
  Cloud points;                          // in the sensor frame (the sector's frame when split)
  std::size_t dropped_non_finite = 0;    // points the reader dropped (NaN or infinite coordinates)
  std::size_t trailing_zero_bytes = 0;   // zero padding after the declared points (accepted)
};

// Scans by number, as the edge's replay loop asks for them: ScanSource in the service, a fake in
// tests.
class ScanProvider {
 public:
  virtual ~ScanProvider() = default;
  // True when no further scan will be read (the recording or the frame limit is exhausted).
  virtual bool done() const = 0;
  // Reads scan number `n` of the recording (which file is the provider's choice; ScanSource: file
  // n mod N); sequence = n. Must not be called when done().
  virtual Expected<ScanFrame> at(std::uint64_t n) = 0;
  // Scans read so far (the service reports a source that gave none); 0 unless counted.
  virtual std::uint64_t emitted() const { return 0; }
  // What is replayed, for the service's start-up line.
  virtual std::string describe() const { return "scans"; }
};

class ScanSource : public ScanProvider {
 public:
  // Lists the scans of `sensor.source`: the *.bin, *.pcd.bin and *.pcd files of a directory
  // sorted by name, or the one file. Errors when the source does not exist, a single file has an
  // unsupported name, or a directory holds no scans. Every read is bounded by `limits` (topology
  // max_scan_bytes): a larger file is an error naming the bound.
  static Expected<ScanSource> open(const SensorConfig& sensor, ReadLimits limits = {});
  // What the kept scans may take in memory: points x sizeof(Point), per source.
  static constexpr std::size_t kDefaultKeptBytes = std::size_t{256} << 20;
  static Expected<ScanSource> open(const SensorConfig& sensor, ReadLimits limits, std::size_t kept_bytes);

  // True once `frames` frames were emitted, or after the last scan when not looping (next(): the
  // last file; at(): as many reads as files), or after a whole pass over the scans emitted nothing
  // (looping could never succeed).
  bool done() const override;

  // Reads the next scan. A file that cannot be read yields an Error naming it and is skipped: the
  // following call continues with the next file. Must not be called when done().
  Expected<ScanFrame> next();

  // Reads scan number `n`, file n mod the number of files, so that every sensor replaying one
  // recording shows the same scan at the same time; sequence = n. An unreadable file is an Error
  // naming it.
  Expected<ScanFrame> at(std::uint64_t n) override;
  const std::vector<std::filesystem::path>& files() const { return files_; }
  std::uint64_t emitted() const override { return emitted_; }
  // Files read from disk so far (a kept scan is not read again).
  std::uint64_t fileReads() const { return file_reads_; }
  // "N scan(s) from SOURCE".
  std::string describe() const override;

 private:
  // A scan as read and cut, to replay without reading it again.
  struct Kept {
    Cloud points;
    std::size_t dropped_non_finite = 0;
    std::size_t trailing_zero_bytes = 0;
  };
  ScanSource(SensorConfig sensor, ReadLimits limits, std::size_t kept_bytes, std::vector<std::filesystem::path> files);
  Expected<ScanFrame> read(std::size_t file_index, std::uint64_t sequence);

  SensorConfig sensor_;
  ReadLimits limits_;
  std::vector<std::filesystem::path> files_;
  std::size_t position_ = 0;          // index into files_ of the next scan to read
  std::uint64_t emitted_ = 0;         // frames emitted so far (= next()'s next sequence number)
  std::uint64_t reads_by_number_ = 0;  // calls of at(), readable or not
  std::size_t failures_in_a_row_ = 0;  // consecutive unreadable files
  std::size_t kept_budget_bytes_ = kDefaultKeptBytes;
  std::size_t kept_bytes_ = 0;
  std::vector<std::optional<Kept>> kept_;  // per file
  std::uint64_t file_reads_ = 0;
  bool exhausted_ = false;            // passed the last scan without looping
};

// The scans of `sensor`, as the edge replays them: a SimScanSource for a simulated LiDAR (source
// sim; services/edge_cluster/sim_scan_source.hpp), else a ScanSource bounded by `limits`. Errors as
// theirs (a missing recording or scene, an unknown LiDAR).
Expected<std::unique_ptr<ScanProvider>> openScanProvider(const SensorConfig& sensor, ReadLimits limits = {});

}  // namespace fogmap
