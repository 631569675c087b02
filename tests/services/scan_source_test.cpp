#include "services/edge_cluster/scan_source.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/cloud_io.hpp"
#include "common/perception/virtual_lidar.hpp"
#include "tests/support/same_points.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;

// A scan of `n` points, so that a frame tells which file it came from by its size.
Cloud scanOf(std::size_t n) {
  Cloud cloud;
  for (std::size_t i = 0; i < n; ++i) {
    const auto v = static_cast<float>(i + 1);
    cloud.push_back({v, -v, 0.5F * v, 0.0F});
  }
  return cloud;
}

using test_support::samePoints;

// Each test replays files from its own fresh directory under the system temp dir.
class ScanSourceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string test_name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    dir_ = fs::temp_directory_path() / ("fogmap_scan_source_" + test_name + "_" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }

  fs::path writeKitti(const std::string& name, std::size_t points) const {
    const fs::path path = dir_ / name;
    EXPECT_TRUE(writeKittiBin(path, scanOf(points)).ok());
    return path;
  }
  fs::path writeBytes(const std::string& name, const std::string& bytes) const {
    const fs::path path = dir_ / name;
    std::ofstream(path, std::ios::binary) << bytes;
    return path;
  }

  SensorConfig sensor(bool loop, std::optional<std::uint64_t> frames = std::nullopt) const {
    SensorConfig config;
    config.source = dir_;
    config.loop = loop;
    config.frames = frames;
    return config;
  }

  // Reads until done (at most `limit` calls), recording each frame's size or -1 for an error.
  static std::vector<long> drain(ScanSource& source, int limit = 100) {
    std::vector<long> sizes;
    for (int i = 0; i < limit && !source.done(); ++i) {
      Expected<ScanFrame> frame = source.next();
      sizes.push_back(frame ? static_cast<long>(frame->points.size()) : -1L);
    }
    return sizes;
  }

  fs::path dir_;
};

TEST_F(ScanSourceTest, ReplaysADirectoryInNameOrderSkippingOtherFiles) {
  writeKitti("0000000002.bin", 3);
  writeKitti("0000000000.bin", 1);
  ASSERT_TRUE(writePcd(dir_ / "0000000001.pcd", scanOf(2)).ok());
  writeBytes("calib.txt", "not a scan");
  fs::create_directories(dir_ / "velodyne.bin");  // a directory, not a scan

  Expected<ScanSource> source = ScanSource::open(sensor(false));
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<fs::path> expected_files = {dir_ / "0000000000.bin", dir_ / "0000000001.pcd",
                                                dir_ / "0000000002.bin"};
  EXPECT_EQ(source->files(), expected_files);

  for (std::uint64_t i = 0; i < 3; ++i) {
    ASSERT_FALSE(source->done());
    Expected<ScanFrame> frame = source->next();
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    EXPECT_EQ(frame->sequence, i);
    EXPECT_EQ(frame->file, expected_files[i]);
    EXPECT_TRUE(samePoints(frame->points, scanOf(i + 1)));
  }
  EXPECT_TRUE(source->done());
}

TEST_F(ScanSourceTest, LoopingKeepsCountingSequenceNumbersUntilTheFrameLimit) {
  writeKitti("a.bin", 1);
  writeKitti("b.bin", 2);
  writeKitti("c.bin", 3);
  Expected<ScanSource> source = ScanSource::open(sensor(true, 7));
  ASSERT_TRUE(source.ok()) << source.error().message;
  std::vector<std::uint64_t> sequences;
  std::vector<std::size_t> sizes;
  while (!source->done() && sequences.size() < 100) {
    Expected<ScanFrame> frame = source->next();
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    sequences.push_back(frame->sequence);
    sizes.push_back(frame->points.size());
  }
  EXPECT_EQ(sequences, (std::vector<std::uint64_t>{0, 1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(sizes, (std::vector<std::size_t>{1, 2, 3, 1, 2, 3, 1}));
  EXPECT_EQ(source->emitted(), 7U);
}

TEST_F(ScanSourceTest, LoopingWithoutALimitDoesNotEnd) {
  writeKitti("a.bin", 1);
  writeKitti("b.bin", 2);
  Expected<ScanSource> source = ScanSource::open(sensor(true));
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(*source, 25).size(), 25U);
  EXPECT_FALSE(source->done());
}

TEST_F(ScanSourceTest, FrameLimitStopsBeforeTheEndOfTheDirectory) {
  writeKitti("a.bin", 1);
  writeKitti("b.bin", 2);
  writeKitti("c.bin", 3);
  Expected<ScanSource> source = ScanSource::open(sensor(false, 2));
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(*source), (std::vector<long>{1, 2}));
}

TEST_F(ScanSourceTest, WithoutLoopingTheEndOfTheDirectoryComesBeforeTheFrameLimit) {
  writeKitti("a.bin", 1);
  writeKitti("b.bin", 2);
  Expected<ScanSource> source = ScanSource::open(sensor(false, 10));
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(*source), (std::vector<long>{1, 2}));
}

TEST_F(ScanSourceTest, AMalformedFileGivesAnErrorNamingItAndReplayContinues) {
  writeKitti("a.bin", 1);
  writeBytes("b.bin", std::string(10, '\0'));  // not a whole number of 16-byte points
  writeKitti("c.bin", 3);
  Expected<ScanSource> source = ScanSource::open(sensor(true, 4));
  ASSERT_TRUE(source.ok()) << source.error().message;

  Expected<ScanFrame> first = source->next();
  ASSERT_TRUE(first.ok()) << first.error().message;
  EXPECT_EQ(first->sequence, 0U);

  Expected<ScanFrame> bad = source->next();
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("b.bin"), std::string::npos) << bad.error().message;

  Expected<ScanFrame> third = source->next();
  ASSERT_TRUE(third.ok()) << third.error().message;
  EXPECT_EQ(third->file, dir_ / "c.bin");
  EXPECT_EQ(third->sequence, 1U) << "a skipped file is not a frame";

  // Around the loop the bad file fails again; the frame limit counts emitted frames only.
  EXPECT_EQ(drain(*source), (std::vector<long>{1, -1, 3}));
  EXPECT_EQ(source->emitted(), 4U);
}

TEST_F(ScanSourceTest, ADirectoryOfOnlyBadFilesEndsAfterOnePassEvenWhenLooping) {
  writeBytes("a.bin", std::string(5, '\0'));
  writeBytes("b.bin", std::string(7, '\0'));
  Expected<ScanSource> source = ScanSource::open(sensor(true));
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(*source), (std::vector<long>{-1, -1}));
  EXPECT_TRUE(source->done());
}

TEST_F(ScanSourceTest, ASingleFileIsReplayedAndLooped) {
  SensorConfig config = sensor(true, 3);
  config.source = writeKitti("only.bin", 4);
  Expected<ScanSource> source = ScanSource::open(config);
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(source->files(), std::vector<fs::path>{config.source});
  EXPECT_EQ(drain(*source), (std::vector<long>{4, 4, 4}));
}

TEST_F(ScanSourceTest, ASplitSensorReturnsItsSectorInTheSectorFrame) {
  Cloud scan;
  for (int degrees = 0; degrees < 360; degrees += 5) {
    const double radians = degrees * 3.14159265358979323846 / 180.0;
    scan.push_back({static_cast<float>(10.0 * std::cos(radians)), static_cast<float>(10.0 * std::sin(radians)), 1.0F,
                    static_cast<float>(degrees)});
  }
  ASSERT_TRUE(writeKittiBin(dir_ / "ring.bin", scan).ok());
  SensorConfig config = sensor(false);
  config.split = SectorSplit{4, 1, 8.0};
  Expected<ScanSource> source = ScanSource::open(config);
  ASSERT_TRUE(source.ok()) << source.error().message;
  Expected<ScanFrame> frame = source->next();
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  EXPECT_TRUE(samePoints(frame->points, sectorView(scan, *config.split)));
  EXPECT_EQ(frame->points.size(), 19U);  // azimuths 90, 95, ..., 180 of [86, 184)
}

TEST_F(ScanSourceTest, ALoopedRecordingIsReadFromDiskOncePerFileAndReplayedAsFirstRead) {
  writeKitti("a.bin", 3);
  writeKitti("b.bin", 5);
  Expected<ScanSource> source = ScanSource::open(sensor(true, 6));
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(*source, 2), (std::vector<long>{3, 5}));
  EXPECT_EQ(source->fileReads(), 2U);
  // The recording changes on disk: the replay keeps what it read (a recording, not a live feed).
  writeKitti("a.bin", 7);
  EXPECT_EQ(drain(*source), (std::vector<long>{3, 5, 3, 5}));
  EXPECT_EQ(source->fileReads(), 2U);
  EXPECT_EQ(source->emitted(), 6U);
}

TEST_F(ScanSourceTest, ScansBeyondTheMemoryBudgetAreReadAgainAndAFailedFileIsNotKept) {
  writeKitti("a.bin", 3);  // 3 points: 48 bytes, within a budget of 64
  writeKitti("b.bin", 5);  // 80 bytes: beyond what is left
  const fs::path bad = writeBytes("c.bin", "12345");  // not a whole number of KITTI records
  Expected<ScanSource> source = ScanSource::open(sensor(true, 6), ReadLimits{}, 3 * sizeof(Point) + 16);
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(*source, 3), (std::vector<long>{3, 5, -1}));
  EXPECT_EQ(source->fileReads(), 3U);
  // Repaired, the file is read again and replays; the kept scan is not read, the other one is.
  writeKitti("c.bin", 2);
  EXPECT_EQ(drain(*source), (std::vector<long>{3, 5, 2, 3}));
  EXPECT_EQ(source->fileReads(), 5U);
}

TEST_F(ScanSourceTest, OpeningFailsForAMissingSourceAnEmptyDirectoryOrAnUnknownFormat) {
  SensorConfig missing = sensor(true);
  missing.source = dir_ / "nowhere";
  Expected<ScanSource> not_there = ScanSource::open(missing);
  ASSERT_FALSE(not_there.ok());
  EXPECT_NE(not_there.error().message.find("nowhere"), std::string::npos);

  writeBytes("readme.txt", "no scans here");
  Expected<ScanSource> empty = ScanSource::open(sensor(true));
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find(dir_.string()), std::string::npos);

  SensorConfig text_file = sensor(true);
  text_file.source = dir_ / "readme.txt";
  EXPECT_FALSE(ScanSource::open(text_file).ok());
}

}  // namespace
}  // namespace fogmap
