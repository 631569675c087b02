// The camera overlay read back as pixels: a KITTI label's projected box lands on its annotated
// 2D box, LiDAR points inside the image are drawn, and unreadable files are named.
#include "tools/fogctl/camera_overlay.hpp"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/cloud_io.hpp"
#include "tests/support/scratch_dir.hpp"

namespace fogmap::cli {
namespace {

namespace fs = std::filesystem;
const fs::path kData = fs::path(FOGMAP_SOURCE_DIR) / "data";

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Pixels that differ between two images of the same size, inside [x0, x1) x [y0, y1).
int changedPixels(const cv::Mat& a, const cv::Mat& b, int x0, int y0, int x1, int y1) {
  int changed = 0;
  for (int y = std::max(0, y0); y < std::min(a.rows, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(a.cols, x1); ++x) changed += a.at<cv::Vec3b>(y, x) != b.at<cv::Vec3b>(y, x) ? 1 : 0;
  }
  return changed;
}

TEST(CameraOverlay, APedestriansProjectedBoxIsDrawnOnItsAnnotatedBoxAndNowhereFar) {
  test_support::ScratchDir dir("overlay");
  const auto calibration = camera::parseKittiCalibration(readText(kData / "kitti_object/calib/000000.txt"));
  ASSERT_TRUE(calibration.ok()) << calibration.error().message;
  const auto labels = camera::parseKittiLabels(readText(kData / "kitti_object/label_2/000000.txt"));
  ASSERT_TRUE(labels.ok()) << labels.error().message;
  ASSERT_EQ(labels->size(), 1U);
  const fs::path image = kData / "kitti_object/image_2/000000.png";
  const fs::path out = dir.path() / "overlay.png";
  const auto counts = writeCameraOverlay(image, *calibration, {}, *labels, {}, out);
  ASSERT_TRUE(counts.ok()) << counts.error().message;
  EXPECT_EQ(counts->boxes_drawn, 1U);
  const cv::Mat before = cv::imread(image.string());
  const cv::Mat after = cv::imread(out.string());
  ASSERT_EQ(after.size(), before.size());
  // The wireframe's edges lie on the annotated box (712 .. 811 x 143 .. 308), within a few pixels.
  const auto& b = (*labels)[0].box;
  EXPECT_GT(changedPixels(before, after, static_cast<int>(b.left) - 6, static_cast<int>(b.top) - 6, static_cast<int>(b.right) + 6,
                          static_cast<int>(b.bottom) + 6),
            400);
  // Far from it (the right third of the image, below the legend) nothing changed.
  EXPECT_EQ(changedPixels(before, after, 900, 100, before.cols, before.rows), 0);
}

TEST(CameraOverlay, LidarPointsAreDrawnWhereTheyProjectAndCounted) {
  test_support::ScratchDir dir("overlay-points");
  const auto calibration = camera::parseKittiCalibration(readText(kData / "kitti_raw_seq_a/calib.txt"));
  ASSERT_TRUE(calibration.ok()) << calibration.error().message;
  const auto scan = readCloud(kData / "kitti_raw_seq_a/0000000000.bin");
  ASSERT_TRUE(scan.ok()) << scan.error().message;
  const fs::path image = kData / "kitti_raw_seq_a/image_02/0000000000.png";
  const auto counts = writeCameraOverlay(image, *calibration, scan->points, {}, {}, dir.path() / "points.png");
  ASSERT_TRUE(counts.ok()) << counts.error().message;
  // A full 360 degree scan: the camera sees the points ahead of it only (about a fifth of them).
  EXPECT_GT(counts->points_drawn, scan->points.size() / 20);
  EXPECT_LT(counts->points_drawn, scan->points.size() / 2);
}

TEST(CameraOverlay, UnreadableImagesAndUnwritableOutputsAreNamed) {
  test_support::ScratchDir dir("overlay-bad");
  camera::KittiCalibration calibration;
  const auto missing = writeCameraOverlay(dir.path() / "nope.png", calibration, {}, {}, {}, dir.path() / "o.png");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("nope.png"), std::string::npos);
  const auto unwritable = writeCameraOverlay(kData / "kitti_object/image_2/000000.png", calibration, {}, {}, {},
                                             dir.path() / "no-such-dir" / "o.png");
  ASSERT_FALSE(unwritable.ok());
  EXPECT_NE(unwritable.error().message.find("no-such-dir"), std::string::npos);
}

}  // namespace
}  // namespace fogmap::cli
