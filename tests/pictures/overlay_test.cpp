// The camera overlay read back as pixels: a KITTI label's projected box lands on its annotated
// 2D box, LiDAR points inside the image are drawn, and unreadable files are named.
#include "pictures/camera_overlay.hpp"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "common/geometry/oriented_box.hpp"
#include "common/io/cloud_io.hpp"
#include "tests/support/scratch_dir.hpp"

namespace fogmap::pictures {
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

// KITTI object frame 000000: its calibration and its one labelled pedestrian.
struct Pedestrian {
  camera::KittiCalibration calibration;
  camera::KittiLabel label;
};
Pedestrian pedestrianOfFrame0() {
  const auto calibration = camera::parseKittiCalibration(readText(kData / "kitti_object/calib/000000.txt"));
  EXPECT_TRUE(calibration.ok()) << calibration.error().message;
  const auto labels = camera::parseKittiLabels(readText(kData / "kitti_object/label_2/000000.txt"));
  EXPECT_TRUE(labels.ok() && labels->size() == 1U);
  return {calibration.ok() ? *calibration : camera::KittiCalibration{}, labels.ok() && !labels->empty() ? labels->front() : camera::KittiLabel{}};
}

// Frame 000000 with `objects` drawn over it into `out`: what was counted, the image before and after.
struct Drawn {
  OverlayCounts counts;
  cv::Mat before, after;
};
Drawn drawObjectsOnFrame0(const camera::KittiCalibration& calibration, const std::vector<MapObject>& objects, const fs::path& out) {
  const fs::path image = kData / "kitti_object/image_2/000000.png";
  const auto counts = writeCameraOverlay(image, calibration, OverlayLayers{.objects = objects}, out);
  EXPECT_TRUE(counts.ok()) << counts.error().message;
  return {counts.ok() ? *counts : OverlayCounts{}, cv::imread(image.string()), cv::imread(out.string())};
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
  const auto counts = writeCameraOverlay(image, *calibration, OverlayLayers{.labels = *labels}, out);
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
  const auto counts = writeCameraOverlay(image, *calibration, OverlayLayers{.lidar_points = scan->points}, dir.path() / "points.png");
  ASSERT_TRUE(counts.ok()) << counts.error().message;
  // A full 360 degree scan: the camera sees the points ahead of it only (about a fifth of them).
  EXPECT_GT(counts->points_drawn, scan->points.size() / 20);
  EXPECT_LT(counts->points_drawn, scan->points.size() / 2);
}

TEST(CameraOverlay, AnObjectsEllipsoidLandsOnItsAnnotatedImageBox) {
  test_support::ScratchDir dir("overlay-objects");
  const auto [calibration, person] = pedestrianOfFrame0();
  // The ellipsoid inscribed in the pedestrian's labelled 3D box, moved to the Velodyne frame (the
  // frame of a map an edge makes of the scan): rectified = A velodyne + b.
  const Eigen::Matrix3d a = calibration.rectification * calibration.velodyne_to_camera.linear();
  const Eigen::Vector3d b = calibration.rectification * calibration.velodyne_to_camera.translation();
  const double h = person.size_hwl.x(), w = person.size_hwl.y(), l = person.size_hwl.z();
  const Eigen::Vector3d centre_rect = person.location - Eigen::Vector3d(0.0, h / 2.0, 0.0);
  const Eigen::Matrix3d yaw = Eigen::AngleAxisd(person.rotation_y, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d shape_rect = yaw * Eigen::Vector3d(l * l / 4.0, h * h / 4.0, w * w / 4.0).asDiagonal() * yaw.transpose();
  Ellipsoid e;
  e.center = a.inverse() * (centre_rect - b);
  e.shape = a.inverse() * shape_rect * a.inverse().transpose();
  MapObject object;
  object.ellipsoids = {e};

  const auto [counts, before, after] = drawObjectsOnFrame0(calibration, {object}, dir.path() / "objects.png");
  EXPECT_EQ(counts.objects_drawn, 1U);
  EXPECT_EQ(counts.object_boxes_drawn, 0U);
  // The annotated box is 712 .. 811 x 143 .. 308; the inscribed ellipsoid's outline lies inside it,
  // touching it at the top and bottom (its height is the box's).
  const auto& box = person.box;
  EXPECT_GT(changedPixels(before, after, static_cast<int>(box.left) - 4, static_cast<int>(box.top) - 4, static_cast<int>(box.right) + 4,
                          static_cast<int>(box.top) + 4),
            30)
      << "the top edge";
  EXPECT_GT(changedPixels(before, after, static_cast<int>(box.left) - 4, static_cast<int>(box.bottom) - 6, static_cast<int>(box.right) + 4,
                          static_cast<int>(box.bottom) + 4),
            30)
      << "the bottom edge";
  EXPECT_EQ(changedPixels(before, after, 900, 100, before.cols, before.rows), 0) << "nothing far from it";
}

TEST(CameraOverlay, AnObjectsOrientedBoxIsDrawnOnItsAnnotatedBoxInItsClasssColour) {
  test_support::ScratchDir dir("overlay-object-box");
  const auto [calibration, person] = pedestrianOfFrame0();
  // The pedestrian's labelled box in the Velodyne frame, as an edge's box (length along yaw, the
  // yaw folded onto the box's axis), on one ellipsoid classed person.
  const camera::VelodyneBox velodyne = camera::labelBoxInVelodyne(person, calibration);
  OrientedBox box;
  box.centre = velodyne.centre;
  box.length = std::max(velodyne.length, velodyne.width);
  box.width = std::min(velodyne.length, velodyne.width);
  box.height = velodyne.height;
  box.yaw = foldedYaw(velodyne.length >= velodyne.width ? velodyne.yaw : velodyne.yaw + M_PI / 2.0);
  Ellipsoid e;
  e.center = velodyne.centre;
  e.shape = Eigen::Matrix3d::Identity() * 0.04;
  e.point_count = 40;
  e.box = box;
  e.label = ObjectLabel{ObjectClass::kPerson, 0.9};
  MapObject object;
  object.ellipsoids = {e};

  const auto [counts, before, after] = drawObjectsOnFrame0(calibration, {object}, dir.path() / "object-box.png");
  EXPECT_EQ(counts.objects_drawn, 1U);
  EXPECT_EQ(counts.object_boxes_drawn, 1U);
  // The same box as the label's wireframe: it lands on the annotated 712 .. 811 x 143 .. 308.
  const auto& b = person.box;
  EXPECT_GT(changedPixels(before, after, static_cast<int>(b.left) - 6, static_cast<int>(b.top) - 6, static_cast<int>(b.right) + 6,
                          static_cast<int>(b.bottom) + 6),
            400);
  EXPECT_EQ(changedPixels(before, after, 900, 100, before.cols, before.rows), 0) << "nothing far from it";
  // Its lines are in the person colour (BGR 60, 20, 220): many pixels there have exactly it.
  int person_coloured = 0;
  for (int y = static_cast<int>(b.top) - 6; y < static_cast<int>(b.bottom) + 6; ++y) {
    for (int x = static_cast<int>(b.left) - 6; x < static_cast<int>(b.right) + 6; ++x) {
      const cv::Vec3b c = after.at<cv::Vec3b>(y, x);
      person_coloured += (c == cv::Vec3b(60, 20, 220)) ? 1 : 0;
    }
  }
  EXPECT_GT(person_coloured, 100);
}

TEST(CameraOverlay, UnreadableImagesAndUnwritableOutputsAreNamed) {
  test_support::ScratchDir dir("overlay-bad");
  camera::KittiCalibration calibration;
  const auto missing = writeCameraOverlay(dir.path() / "nope.png", calibration, {}, dir.path() / "o.png");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("nope.png"), std::string::npos);
  const auto unwritable = writeCameraOverlay(kData / "kitti_object/image_2/000000.png", calibration, {},
                                             dir.path() / "no-such-dir" / "o.png");
  ASSERT_FALSE(unwritable.ok());
  EXPECT_NE(unwritable.error().message.find("no-such-dir"), std::string::npos);
}

}  // namespace
}  // namespace fogmap::pictures
