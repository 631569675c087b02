#include "common/io/cloud_io.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;

using test_support::kSourceDir;

// Each test writes its files into its own fresh directory under the system temp dir.
class CloudIo : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string test_name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    dir_ = fs::temp_directory_path() /
           ("fogmap_cloud_io_" + test_name + "_" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }

  fs::path file(const std::string& name) const { return dir_ / name; }

  fs::path writeBytes(const std::string& name, const std::string& bytes) const {
    const fs::path path = file(name);
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

  fs::path dir_;
};

Cloud sampleCloud() {
  return {{1.0F, 2.0F, 3.0F, 0.5F},
          {-4.25F, 0.125F, -1.73F, 0.0F},
          {70.5F, -55.0F, 2.9F, 0.99F},
          {0.0F, 0.0F, 0.0F, 255.0F}};
}

std::string floatBytes(std::initializer_list<float> values) {
  std::string bytes(values.size() * sizeof(float), '\0');
  std::memcpy(bytes.data(), values.begin(), bytes.size());
  return bytes;
}

void expectSamePoints(const Cloud& actual, const Cloud& expected, float tolerance = 0.0F) {
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_NEAR(actual[i].x, expected[i].x, tolerance) << "point " << i;
    EXPECT_NEAR(actual[i].y, expected[i].y, tolerance) << "point " << i;
    EXPECT_NEAR(actual[i].z, expected[i].z, tolerance) << "point " << i;
    EXPECT_NEAR(actual[i].intensity, expected[i].intensity, tolerance) << "point " << i;
  }
}

// The read failed with `code` and a message naming the file and containing every `phrase`.
void expectRejected(const Expected<LoadedCloud>& result, const fs::path& path, std::initializer_list<std::string> phrases,
                    ErrorCode code = ErrorCode::kInvalidArgument) {
  ASSERT_FALSE(result.ok()) << path << " was accepted with " << result->points.size() << " points";
  const std::string& message = result.error().message;
  EXPECT_EQ(result.error().code, code) << message;
  EXPECT_NE(message.find(path.filename().string()), std::string::npos) << "no file name in: " << message;
  for (const std::string& phrase : phrases) {
    EXPECT_NE(message.find(phrase), std::string::npos) << "'" << phrase << "' not in: " << message;
  }
}

pcl::PointCloud<pcl::PointXYZI> toPcl(const Cloud& cloud) {
  pcl::PointCloud<pcl::PointXYZI> out;
  for (const Point& p : cloud) {
    pcl::PointXYZI q;
    q.x = p.x;
    q.y = p.y;
    q.z = p.z;
    q.intensity = p.intensity;
    out.push_back(q);
  }
  return out;
}

std::string asciiPcd(const std::string& fields_lines, int points, const std::string& data) {
  return "VERSION 0.7\n" + fields_lines + "WIDTH " + std::to_string(points) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n" +
         "POINTS " + std::to_string(points) + "\nDATA ascii\n" + data;
}

const std::string kXyzFields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";

// ---- round trips and real data -----------------------------------------------------------------

TEST_F(CloudIo, KittiRoundTripPreservesPointsExactly) {
  const fs::path path = file("scan.bin");
  ASSERT_TRUE(writeKittiBin(path, sampleCloud()).ok());
  EXPECT_EQ(fs::file_size(path), 4u * 16u);
  const Expected<LoadedCloud> loaded = readKittiBin(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, sampleCloud());
  EXPECT_EQ(loaded->dropped_non_finite, 0u);
}

TEST_F(CloudIo, BinaryPcdRoundTripPreservesPointsExactly) {
  const fs::path path = file("scan.pcd");
  ASSERT_TRUE(writePcd(path, sampleCloud()).ok());
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, sampleCloud());
}

TEST_F(CloudIo, PclReadsThePcdWeWrite) {
  const fs::path path = file("scan.pcd");
  ASSERT_TRUE(writePcd(path, sampleCloud()).ok());
  pcl::PointCloud<pcl::PointXYZI> pcl_cloud;
  ASSERT_EQ(pcl::io::loadPCDFile(path.string(), pcl_cloud), 0);
  ASSERT_EQ(pcl_cloud.size(), sampleCloud().size());
  EXPECT_EQ(pcl_cloud[2].x, 70.5F);
  EXPECT_EQ(pcl_cloud[2].intensity, 0.99F);
}

TEST_F(CloudIo, EmptyCloudRoundTripsThroughPcd) {
  const fs::path path = file("empty_cloud.pcd");
  ASSERT_TRUE(writePcd(path, {}).ok());
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_TRUE(loaded->points.empty());
}

TEST_F(CloudIo, ReadsAsciiPcdWrittenByPcl) {
  const fs::path path = file("ascii.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeASCII(path.string(), toPcl(sampleCloud()), 9), 0);
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, sampleCloud(), 1e-5F);
}

TEST_F(CloudIo, ReadsBinaryCompressedPcdWrittenByPcl) {
  const fs::path path = file("compressed.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(path.string(), toPcl(sampleCloud())), 0);
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, sampleCloud());
}

TEST_F(CloudIo, ReadsPcdWithoutIntensityAsZeroIntensity) {
  pcl::PointCloud<pcl::PointXYZ> xyz;
  xyz.push_back(pcl::PointXYZ(1.0F, 2.0F, 3.0F));
  xyz.push_back(pcl::PointXYZ(-1.0F, -2.0F, -3.0F));
  const fs::path path = file("xyz_only.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinary(path.string(), xyz), 0);
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, {{1.0F, 2.0F, 3.0F, 0.0F}, {-1.0F, -2.0F, -3.0F, 0.0F}});
}

TEST_F(CloudIo, ReadsPcdWithDoubleAndIntegerFields) {
  const std::string fields = "FIELDS x y z intensity\nSIZE 8 8 8 2\nTYPE F F F U\nCOUNT 1 1 1 1\n";
  const fs::path path = writeBytes("mixed.pcd", asciiPcd(fields, 2, "1.5 -2.25 3 7\n0 0 0.125 65535\n"));
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, {{1.5F, -2.25F, 3.0F, 7.0F}, {0.0F, 0.0F, 0.125F, 65535.0F}});
}

TEST_F(CloudIo, ReadsBundledKittiScan) {
  const fs::path path = kSourceDir / "data/kitti_raw_seq_a/0000000000.bin";
  const Expected<LoadedCloud> loaded = readKittiBin(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->points.size(), 114278u);
  EXPECT_EQ(loaded->dropped_non_finite, 0u);
  // Ranges from data/README.md: catches a wrong record layout or stride.
  float min_z = std::numeric_limits<float>::max();
  float max_intensity = 0.0F;
  for (const Point& p : loaded->points) {
    min_z = std::min(min_z, p.z);
    max_intensity = std::max(max_intensity, p.intensity);
  }
  EXPECT_NEAR(min_z, -19.24F, 0.01F);
  EXPECT_LE(max_intensity, 1.0F);
  EXPECT_GT(max_intensity, 0.9F);
}

TEST_F(CloudIo, ReadCloudChoosesTheFormatFromTheFileName) {
  // Three 20-byte nuScenes records (x y z intensity ring) make 60 bytes, not a KITTI size.
  const std::string records = floatBytes({1, 2, 3, 100, 5, 4, 5, 6, 200, 31, 7, 8, 9, 0, 0});
  const fs::path nuscenes = writeBytes("sweep.pcd.bin", records);
  const Expected<LoadedCloud> loaded = readCloud(nuscenes);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, {{1, 2, 3, 100}, {4, 5, 6, 200}, {7, 8, 9, 0}});

  const fs::path kitti = file("scan.bin");
  ASSERT_TRUE(writeKittiBin(kitti, sampleCloud()).ok());
  ASSERT_TRUE(readCloud(kitti).ok());
  EXPECT_EQ(readCloud(kitti)->points.size(), 4u);

  const fs::path pcd = file("scan.pcd");
  ASSERT_TRUE(writePcd(pcd, sampleCloud()).ok());
  ASSERT_TRUE(readCloud(pcd).ok());
  EXPECT_EQ(readCloud(pcd)->points.size(), 4u);
}

TEST_F(CloudIo, FormatFromPathRecognisesTheThreeFormats) {
  EXPECT_EQ(*cloudFormatFromPath("a/b/0000000000.bin"), CloudFormat::kKittiBin);
  EXPECT_EQ(*cloudFormatFromPath("n015__LIDAR_TOP__1532402927647951.pcd.bin"), CloudFormat::kNuscenesBin);
  EXPECT_EQ(*cloudFormatFromPath("map.pcd"), CloudFormat::kPcd);
  const Expected<CloudFormat> unknown = cloudFormatFromPath("scan.ply");
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(unknown.error().message.find("scan.ply"), std::string::npos) << unknown.error().message;
  EXPECT_NE(unknown.error().message.find("unknown point cloud format"), std::string::npos) << unknown.error().message;
}

TEST_F(CloudIo, DropsAndCountsNonFiniteKittiPoints) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const fs::path path = writeBytes("non_finite.bin", floatBytes({1, 2, 3, 0.5F,     // kept
                                                                 nan, 0, 0, 0,      // dropped
                                                                 0, -inf, 0, 0,     // dropped
                                                                 0, 0, inf, 0,      // dropped
                                                                 4, 5, 6, 0.25F}));  // kept
  const Expected<LoadedCloud> loaded = readKittiBin(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, {{1, 2, 3, 0.5F}, {4, 5, 6, 0.25F}});
  EXPECT_EQ(loaded->dropped_non_finite, 3u);
}

TEST_F(CloudIo, DropsAndCountsNonFinitePcdPoints) {
  Cloud cloud = sampleCloud();
  cloud[1].y = std::numeric_limits<float>::quiet_NaN();
  const fs::path path = file("non_finite.pcd");
  ASSERT_TRUE(writePcd(path, cloud).ok());
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->points.size(), 3u);
  EXPECT_EQ(loaded->dropped_non_finite, 1u);

  const fs::path ascii = writeBytes("non_finite_ascii.pcd", asciiPcd(kXyzFields, 2, "1 2 3\nnan 0 0\n"));
  const Expected<LoadedCloud> loaded_ascii = readPcd(ascii);
  ASSERT_TRUE(loaded_ascii.ok()) << loaded_ascii.error().message;
  EXPECT_EQ(loaded_ascii->points.size(), 1u);
  EXPECT_EQ(loaded_ascii->dropped_non_finite, 1u);
}

// ---- malformed files ------------------------------------------------------------------------

TEST_F(CloudIo, RejectsEmptyKittiFile) {
  const fs::path path = writeBytes("empty.bin", "");
  expectRejected(readKittiBin(path), path, {"empty"});
}

TEST_F(CloudIo, RejectsEmptyPcdFile) {
  const fs::path path = writeBytes("empty.pcd", "");
  expectRejected(readPcd(path), path, {"empty"});
}

TEST_F(CloudIo, RejectsKittiFileWhoseSizeIsNotAMultipleOf16) {
  // A truncated last record and trailing bytes look the same: the size does not divide by 16.
  const fs::path truncated = writeBytes("truncated.bin", floatBytes({1, 2, 3, 0.5F, 4, 5, 6}));
  expectRejected(readKittiBin(truncated), truncated, {"28 bytes", "not a multiple of the 16-byte"});

  std::string with_garbage = floatBytes({1, 2, 3, 0.5F});
  with_garbage += "xyz";
  const fs::path garbage = writeBytes("garbage.bin", with_garbage);
  expectRejected(readKittiBin(garbage), garbage, {"19 bytes", "not a multiple of the 16-byte"});
}

TEST_F(CloudIo, RejectsNuscenesFileWhoseSizeIsNotAMultipleOf20) {
  // 64 bytes: a whole number of KITTI records, but not of 20-byte nuScenes records.
  const fs::path path = writeBytes("sweep.pcd.bin", floatBytes({1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16}));
  expectRejected(readNuscenesBin(path), path, {"64 bytes", "not a multiple of the 20-byte"});
  expectRejected(readCloud(path), path, {"not a multiple of the 20-byte"});
}

TEST_F(CloudIo, RejectsTruncatedBinaryPcd) {
  const fs::path path = file("truncated.pcd");
  ASSERT_TRUE(writePcd(path, sampleCloud()).ok());
  fs::resize_file(path, fs::file_size(path) - 5);
  expectRejected(readPcd(path), path, {"truncated", "4 points", "64 bytes", "59 bytes"});
}

TEST_F(CloudIo, RejectsBinaryPcdWithTrailingGarbage) {
  const fs::path path = file("trailing.pcd");
  ASSERT_TRUE(writePcd(path, sampleCloud()).ok());
  std::ofstream(path, std::ios::binary | std::ios::app) << "garbage";
  expectRejected(readPcd(path), path, {"7 bytes of trailing data", "4 points"});
}

TEST_F(CloudIo, RejectsTruncatedBinaryCompressedPcd) {
  const fs::path path = file("compressed.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(path.string(), toPcl(sampleCloud())), 0);
  fs::resize_file(path, fs::file_size(path) - 3);
  expectRejected(readPcd(path), path, {"truncated"});
}

TEST_F(CloudIo, RejectsBinaryCompressedPcdWithTrailingGarbage) {
  const fs::path path = file("compressed.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(path.string(), toPcl(sampleCloud())), 0);
  std::ofstream(path, std::ios::binary | std::ios::app) << "junk";
  expectRejected(readPcd(path), path, {"4 bytes of trailing data"});
}

TEST_F(CloudIo, RejectsAsciiPcdWithFewerPointsThanDeclared) {
  const fs::path path = writeBytes("fewer.pcd", asciiPcd(kXyzFields, 100, "1 2 3\n4 5 6\n7 8 9\n"));
  expectRejected(readPcd(path), path, {"count mismatch", "POINTS says 100", "has 3 points"});
}

TEST_F(CloudIo, RejectsAsciiPcdWithMorePointsThanDeclared) {
  const fs::path path = writeBytes("more.pcd", asciiPcd(kXyzFields, 2, "1 2 3\n4 5 6\n7 8 9\n"));
  expectRejected(readPcd(path), path, {"count mismatch", "POINTS says 2", "has 3 points"});
}

TEST_F(CloudIo, RejectsPcdWhoseWidthTimesHeightDisagreesWithPoints) {
  const std::string pcd = "VERSION 0.7\n" + kXyzFields + "WIDTH 5\nHEIGHT 2\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n7 8 9\n";
  const fs::path path = writeBytes("width.pcd", pcd);
  expectRejected(readPcd(path), path, {"count mismatch", "5 x 2", "POINTS = 3"});
}

TEST_F(CloudIo, RejectsAsciiPcdWithWrongNumberOfValuesOnALine) {
  const fs::path path = writeBytes("short_line.pcd", asciiPcd(kXyzFields, 2, "1 2 3\n4 5\n"));
  expectRejected(readPcd(path), path, {"line 2 has 2 values, expected 3"});
}

TEST_F(CloudIo, RejectsAsciiPcdWithNonNumericValue) {
  const fs::path path = writeBytes("word.pcd", asciiPcd(kXyzFields, 2, "1 2 3\n4 five 6\n"));
  expectRejected(readPcd(path), path, {"not a number", "'five'"});
}

TEST_F(CloudIo, RejectsPcdWithoutZField) {
  const std::string fields = "FIELDS x y intensity\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  const fs::path path = writeBytes("no_z.pcd", asciiPcd(fields, 1, "1 2 3\n"));
  expectRejected(readPcd(path), path, {"no 'z' field"});
}

TEST_F(CloudIo, RejectsPcdWithGarbageHeader) {
  std::string garbage = "hello this is not a point cloud\n";
  garbage += floatBytes({1, 2, 3, 4});
  const fs::path path = writeBytes("garbage.pcd", garbage);
  expectRejected(readPcd(path), path, {"unparseable PCD header", "line 1", "hello this is not"});

  const fs::path no_data = writeBytes("no_data.pcd", "VERSION 0.7\n" + kXyzFields + "POINTS 1\n");
  expectRejected(readPcd(no_data), no_data, {"unparseable PCD header", "without a DATA line"});

  const fs::path bad_size = writeBytes("bad_size.pcd", asciiPcd("FIELDS x y z\nSIZE 4 four 4\nTYPE F F F\n", 1, "1 2 3\n"));
  expectRejected(readPcd(bad_size), bad_size, {"unparseable PCD header", "invalid SIZE/TYPE"});

  const fs::path bad_points = writeBytes("bad_points.pcd", "VERSION 0.7\n" + kXyzFields + "POINTS -3\nDATA ascii\n");
  expectRejected(readPcd(bad_points), bad_points, {"unparseable PCD header", "POINTS"});

  // PCL would stop its header at this line and read zero points.
  const fs::path blank = writeBytes("blank.pcd", "VERSION 0.7\n \t\n" + kXyzFields + "POINTS 1\nDATA ascii\n1 2 3\n");
  expectRejected(readPcd(blank), blank, {"unparseable PCD header", "line 2 holds only whitespace"});
}

// Found by fuzzing: PCL sizes its point buffer when it reads POINTS, from the fields read by then,
// so a COUNT line after POINTS made it write 200 values per point into room for 3.
TEST_F(CloudIo, RejectsPcdWithFieldLinesAfterPoints) {
  std::string data;
  for (int point = 0; point < 8; ++point) {
    for (int value = 0; value < 202; ++value) data += "1 ";
    data += "\n";
  }
  const fs::path count = writeBytes("count_after_points.pcd",
                                    "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 8\nCOUNT 1 1 200\nDATA ascii\n" + data);
  expectRejected(readPcd(count), count, {"unparseable PCD header", "COUNT comes after POINTS"});

  const fs::path size = writeBytes("size_after_points.pcd", "FIELDS x y z\nPOINTS 1\nSIZE 8 8 8\nTYPE F F F\nDATA ascii\n1 2 3\n");
  expectRejected(readPcd(size), size, {"unparseable PCD header", "SIZE comes after POINTS"});
}

TEST_F(CloudIo, RejectsPcdWithARepeatedHeaderLine) {
  const fs::path fields = writeBytes("fields_twice.pcd", "FIELDS a b\nCOLUMNS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\n"
                                                         "DATA ascii\n1 2 3\n");
  expectRejected(readPcd(fields), fields, {"unparseable PCD header", "FIELDS appears twice (line 2)"});
  const fs::path points = writeBytes("points_twice.pcd", asciiPcd(kXyzFields + "POINTS 1\n", 2, "1 2 3\n4 5 6\n"));
  expectRejected(readPcd(points), points, {"unparseable PCD header", "POINTS appears twice"});
}

// Found by fuzzing: WIDTH x HEIGHT wrapped around 2^64 and matched POINTS.
TEST_F(CloudIo, RejectsPcdWhoseWidthTimesHeightOverflows) {
  const fs::path zero = writeBytes("wraps_to_zero.pcd", "VERSION 0.7\n" + kXyzFields +
                                                         "WIDTH 4294967296\nHEIGHT 4294967296\nPOINTS 0\nDATA ascii\n");
  expectRejected(readPcd(zero), zero, {"count mismatch", "4294967296 x 4294967296", "POINTS = 0"});
  const fs::path one = writeBytes("wraps_to_one.pcd", "VERSION 0.7\n" + kXyzFields +
                                                       "WIDTH 3\nHEIGHT 12297829382473034411\nPOINTS 1\nDATA ascii\n1 2 3\n");
  expectRejected(readPcd(one), one, {"count mismatch", "3 x 12297829382473034411", "POINTS = 1"});
}

TEST_F(CloudIo, RejectsPcdWithAnEmptyCountLine) {
  const fs::path path = writeBytes("empty_count.pcd", asciiPcd("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT\n", 1, "1 2 3\n"));
  expectRejected(readPcd(path), path, {"unparseable PCD header", "COUNT lists 0 entries for 3 fields"});
}

TEST_F(CloudIo, RejectsBinaryCompressedPcdWithPaddingFields) {
  const std::string header = "VERSION 0.7\nFIELDS x _ y z\nSIZE 4 4 4 4\nTYPE F F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
                             "DATA binary_compressed\n";
  const fs::path path = writeBytes("padded.pcd", header + floatBytes({0, 0, 0, 0, 0}));
  expectRejected(readPcd(path), path, {"binary_compressed", "padding ('_') fields are not supported"});
}

TEST_F(CloudIo, RejectsBinaryCompressedPcdWithACorruptBlock) {
  const fs::path path = file("corrupt.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(path.string(), toPcl(sampleCloud())), 0);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::size_t data = bytes.find("DATA binary_compressed\n");
  ASSERT_NE(data, std::string::npos);
  // The block's first control byte becomes a back reference to before the start of the output.
  bytes[data + std::string("DATA binary_compressed\n").size() + 8] = static_cast<char>(0xFF);
  const fs::path corrupt = writeBytes("corrupt_block.pcd", bytes);
  expectRejected(readPcd(corrupt), corrupt, {"binary_compressed data does not decompress"});
}

TEST_F(CloudIo, ParsesBytesInMemoryAsTheFileReadersDo) {
  const fs::path kitti = file("scan.bin");
  const fs::path pcd = file("scan.pcd");
  ASSERT_TRUE(writeKittiBin(kitti, sampleCloud()).ok());
  ASSERT_TRUE(writePcd(pcd, sampleCloud()).ok());
  const auto bytesOf = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  const Expected<LoadedCloud> from_kitti = parseKittiBin(bytesOf(kitti), "memory");
  ASSERT_TRUE(from_kitti.ok()) << from_kitti.error().message;
  expectSamePoints(from_kitti->points, sampleCloud());
  const Expected<LoadedCloud> from_pcd = parsePcd(bytesOf(pcd), "memory");
  ASSERT_TRUE(from_pcd.ok()) << from_pcd.error().message;
  expectSamePoints(from_pcd->points, sampleCloud());

  // Errors start with the name given; the size bound holds as for files.
  const Expected<LoadedCloud> empty = parseNuscenesBin("", "sweep 7");
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.error().message, "sweep 7: the file is empty (0 bytes)");
  const Expected<LoadedCloud> large = parseKittiBin(bytesOf(kitti), "memory", ReadLimits{.max_bytes = 16});
  ASSERT_FALSE(large.ok());
  EXPECT_NE(large.error().message.find("more than the scan size bound of 16 bytes"), std::string::npos)
      << large.error().message;
}

TEST_F(CloudIo, ReadsAsciiPcdWithCrlfLineEndings) {
  const std::string pcd = "VERSION 0.7\r\nFIELDS x y z\r\nSIZE 4 4 4\r\nTYPE F F F\r\nWIDTH 2\r\nHEIGHT 1\r\n"
                          "POINTS 2\r\nDATA ascii\r\n1 2 3\r\n4 5 6\r\n";
  const fs::path path = writeBytes("crlf.pcd", pcd);
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, {{1, 2, 3, 0}, {4, 5, 6, 0}});
}

TEST_F(CloudIo, RejectsRandomBytesAsPcdWithoutCrashing) {
  std::mt19937 rng(7);
  std::string bytes(4096, '\0');
  for (char& c : bytes) c = static_cast<char>(rng() & 0xFF);
  const fs::path path = writeBytes("random.pcd", bytes);
  expectRejected(readPcd(path), path, {"unparseable PCD header"});
}

TEST_F(CloudIo, RejectsMissingFileAsNotFound) {
  const fs::path kitti = file("missing.bin");
  expectRejected(readKittiBin(kitti), kitti, {"no such file"}, ErrorCode::kNotFound);
  const fs::path nuscenes = file("missing.pcd.bin");
  expectRejected(readNuscenesBin(nuscenes), nuscenes, {"no such file"}, ErrorCode::kNotFound);
  const fs::path pcd = file("missing.pcd");
  expectRejected(readPcd(pcd), pcd, {"no such file"}, ErrorCode::kNotFound);
  expectRejected(readCloud(pcd), pcd, {"no such file"}, ErrorCode::kNotFound);
}

TEST_F(CloudIo, WritingIntoAMissingDirectoryIsAnIoError) {
  const fs::path path = file("no/such/dir/scan.bin");
  const Status kitti = writeKittiBin(path, sampleCloud());
  ASSERT_FALSE(kitti.ok());
  EXPECT_EQ(kitti.error().code, ErrorCode::kIo);
  EXPECT_NE(kitti.error().message.find("scan.bin"), std::string::npos) << kitti.error().message;
  const Status pcd = writePcd(file("no/such/dir/scan.pcd"), sampleCloud());
  ASSERT_FALSE(pcd.ok());
  EXPECT_EQ(pcd.error().code, ErrorCode::kIo);
}

// ---- trailing zero padding -----------------------------------------------------------------------
// A real KITTI PCD export carries this many zero bytes after its declared points; PCL reads it.
constexpr std::size_t kExportPadding = 3906;

void appendBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::app);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

TEST_F(CloudIo, AcceptsBinaryPcdWithTrailingZeroPaddingAndCountsIt) {
  const fs::path plain = file("plain.pcd");
  ASSERT_TRUE(writePcd(plain, sampleCloud()).ok());
  const Expected<LoadedCloud> unpadded = readPcd(plain);
  ASSERT_TRUE(unpadded.ok()) << unpadded.error().message;
  EXPECT_EQ(unpadded->trailing_zero_bytes, 0u);

  const fs::path path = file("padded.pcd");
  ASSERT_TRUE(writePcd(path, sampleCloud()).ok());
  appendBytes(path, std::string(kExportPadding, '\0'));
  for (const Expected<LoadedCloud>& loaded : {readPcd(path), readCloud(path)}) {
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    expectSamePoints(loaded->points, sampleCloud());
    EXPECT_EQ(loaded->trailing_zero_bytes, kExportPadding);
    EXPECT_EQ(loaded->dropped_non_finite, 0u);
  }
}

TEST_F(CloudIo, AcceptsBinaryCompressedPcdWithTrailingZeroPadding) {
  const fs::path path = file("compressed_padded.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(path.string(), toPcl(sampleCloud())), 0);
  appendBytes(path, std::string(kExportPadding, '\0'));
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, sampleCloud());
  EXPECT_EQ(loaded->trailing_zero_bytes, kExportPadding);
}

TEST_F(CloudIo, AcceptsAsciiPcdWithTrailingZeroPadding) {
  const fs::path path =
      writeBytes("ascii_padded.pcd", asciiPcd(kXyzFields, 2, "1 2 3\n4 5 6\n") + std::string(kExportPadding, '\0'));
  const Expected<LoadedCloud> loaded = readPcd(path);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expectSamePoints(loaded->points, {{1, 2, 3, 0}, {4, 5, 6, 0}});
  EXPECT_EQ(loaded->trailing_zero_bytes, kExportPadding);
}

TEST_F(CloudIo, RejectsPcdPaddingWithANonZeroByte) {
  std::string padding(kExportPadding, '\0');
  padding[1000] = '\x01';

  const fs::path binary = file("binary_dirty_padding.pcd");
  ASSERT_TRUE(writePcd(binary, sampleCloud()).ok());
  const std::uintmax_t binary_size = fs::file_size(binary);
  appendBytes(binary, padding);
  expectRejected(readPcd(binary), binary,
                 {"3906 bytes of trailing data", "4 points", "byte " + std::to_string(binary_size + 1000) + " of the file is not zero"});

  const fs::path compressed = file("compressed_dirty_padding.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(compressed.string(), toPcl(sampleCloud())), 0);
  const std::uintmax_t compressed_size = fs::file_size(compressed);
  appendBytes(compressed, padding);
  expectRejected(readPcd(compressed), compressed,
                 {"3906 bytes of trailing data", "byte " + std::to_string(compressed_size + 1000) + " of the file is not zero"});

  // In ascii data the dirty padding reads as a third, malformed data line.
  const fs::path ascii = writeBytes("ascii_dirty_padding.pcd", asciiPcd(kXyzFields, 2, "1 2 3\n4 5 6\n") + padding);
  expectRejected(readPcd(ascii), ascii, {"PCD data line 3"});
}

// ---- read limits ---------------------------------------------------------------------------------

TEST_F(CloudIo, RefusesAFileAboveTheSizeBoundNamingTheBound) {
  const fs::path kitti = file("scan.bin");
  ASSERT_TRUE(writeKittiBin(kitti, sampleCloud()).ok());  // 64 bytes
  expectRejected(readKittiBin(kitti, ReadLimits{.max_bytes = 63}), kitti,
                 {"64 bytes", "bound of 63 bytes", "max_scan_bytes"});
  expectRejected(readCloud(kitti, ReadLimits{.max_bytes = 63}), kitti, {"bound of 63 bytes"});
  const Expected<LoadedCloud> at_bound = readKittiBin(kitti, ReadLimits{.max_bytes = 64});
  ASSERT_TRUE(at_bound.ok()) << at_bound.error().message;
  EXPECT_EQ(at_bound->points.size(), 4u);

  const fs::path pcd = file("scan.pcd");
  ASSERT_TRUE(writePcd(pcd, sampleCloud()).ok());
  const std::uintmax_t pcd_size = fs::file_size(pcd);
  expectRejected(readPcd(pcd, ReadLimits{.max_bytes = pcd_size - 1}), pcd,
                 {"bound of " + std::to_string(pcd_size - 1) + " bytes"});
  EXPECT_TRUE(readPcd(pcd, ReadLimits{.max_bytes = pcd_size}).ok());
}

TEST_F(CloudIo, RefusesAFileAboveTheDefaultBoundBeforeReadingIt) {
  // Sparse, so it costs no disk: whole KITTI records of zeros that would read as valid points
  // if the size were not checked first.
  const fs::path path = file("huge.bin");
  std::ofstream(path, std::ios::binary).close();
  fs::resize_file(path, kDefaultMaxScanBytes + 16);
  expectRejected(readKittiBin(path), path,
                 {std::to_string(kDefaultMaxScanBytes + 16) + " bytes", "bound of " + std::to_string(kDefaultMaxScanBytes)});
}

TEST_F(CloudIo, KeepsNonFiniteKittiPointsInPlaceWhenAsked) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const fs::path path = writeBytes("non_finite.bin", floatBytes({1, 2, 3, 0.5F,      //
                                                                 nan, 0, 0, 0,       //
                                                                 0, -inf, 0, 0,      //
                                                                 0, 0, inf, 0,       //
                                                                 4, 5, 6, 0.25F}));
  const Expected<LoadedCloud> loaded = readKittiBin(path, ReadLimits{.keep_non_finite = true});
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  ASSERT_EQ(loaded->points.size(), 5u);
  EXPECT_EQ(loaded->kept_non_finite, 3u);
  EXPECT_EQ(loaded->dropped_non_finite, 0u);
  EXPECT_EQ(loaded->points[0].x, 1.0F);
  EXPECT_TRUE(std::isnan(loaded->points[1].x));
  EXPECT_EQ(loaded->points[2].y, -inf);
  EXPECT_EQ(loaded->points[3].z, inf);
  EXPECT_EQ(loaded->points[4].x, 4.0F);
  EXPECT_EQ(loaded->points[4].intensity, 0.25F);
}

TEST_F(CloudIo, KeepsNonFinitePcdPointsInPlaceWhenAsked) {
  const ReadLimits keep{.keep_non_finite = true};
  Cloud cloud = sampleCloud();
  cloud[1].y = std::numeric_limits<float>::quiet_NaN();
  cloud[3].z = std::numeric_limits<float>::infinity();
  const auto expectInPlace = [&](const Expected<LoadedCloud>& loaded) {
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    ASSERT_EQ(loaded->points.size(), 4u);
    EXPECT_EQ(loaded->kept_non_finite, 2u);
    EXPECT_EQ(loaded->dropped_non_finite, 0u);
    EXPECT_EQ(loaded->points[0].x, cloud[0].x);
    EXPECT_EQ(loaded->points[1].x, cloud[1].x);
    EXPECT_TRUE(std::isnan(loaded->points[1].y));
    EXPECT_EQ(loaded->points[2].x, cloud[2].x);
    EXPECT_EQ(loaded->points[3].intensity, cloud[3].intensity);
    EXPECT_TRUE(std::isinf(loaded->points[3].z));
  };
  const fs::path binary = file("non_finite.pcd");
  ASSERT_TRUE(writePcd(binary, cloud).ok());
  {
    SCOPED_TRACE("binary");
    expectInPlace(readPcd(binary, keep));
  }
  const fs::path compressed = file("non_finite_compressed.pcd");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(compressed.string(), toPcl(cloud)), 0);
  {
    SCOPED_TRACE("binary_compressed");
    expectInPlace(readPcd(compressed, keep));
  }

  const fs::path ascii = writeBytes("non_finite_ascii.pcd", asciiPcd(kXyzFields, 3, "1 2 3\nnan 0 0\n4 5 6\n"));
  const Expected<LoadedCloud> loaded_ascii = readPcd(ascii, keep);
  ASSERT_TRUE(loaded_ascii.ok()) << loaded_ascii.error().message;
  ASSERT_EQ(loaded_ascii->points.size(), 3u);
  EXPECT_EQ(loaded_ascii->kept_non_finite, 1u);
  EXPECT_EQ(loaded_ascii->points[0].x, 1.0F);
  EXPECT_TRUE(std::isnan(loaded_ascii->points[1].x));
  EXPECT_EQ(loaded_ascii->points[2].x, 4.0F);
}

}  // namespace
}  // namespace fogmap
