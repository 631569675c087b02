// KITTI calibration and labels: the projection chain checked against KITTI's own annotations.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <fstream>
#include <sstream>

#include "common/camera/kitti.hpp"
#include "common/camera/pinhole.hpp"
#include "common/io/cloud_io.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap::camera {
namespace {

using test_support::dataDir;

constexpr int kWidth = 1242;  // KITTI's image_2 of frames 000001 and 000002
constexpr int kHeight = 375;

std::string slurp(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

struct Frame {
  KittiCalibration calib;
  std::vector<KittiLabel> labels;
};

Frame frame(const std::string& id) {
  const auto calib = parseKittiCalibration(slurp(dataDir() / "kitti_object" / "calib" / (id + ".txt")));
  EXPECT_TRUE(calib.ok()) << (calib ? "" : calib.error().message);
  const auto labels = parseKittiLabels(slurp(dataDir() / "kitti_object" / "label_2" / (id + ".txt")));
  EXPECT_TRUE(labels.ok()) << (labels ? "" : labels.error().message);
  return {calib ? *calib : KittiCalibration{}, labels ? *labels : std::vector<KittiLabel>{}};
}

TEST(KittiCamera, ProjectedLabelBoxesFallOnTheirAnnotatedImageBoxes) {
  std::size_t checked = 0;
  for (const std::string id : {"000001", "000002"}) {
    const Frame f = frame(id);
    ASSERT_FALSE(f.labels.empty()) << id;
    for (const KittiLabel& l : f.labels) {
      if (l.type == "DontCare" || l.truncated > 0.0) continue;
      SCOPED_TRACE(id + " " + l.type);
      const auto box = projectBox(f.calib.projection[2], boxCorners(l), kWidth, kHeight);
      ASSERT_TRUE(box.has_value());
      // KITTI's 2D boxes were drawn by hand around the visible object: its projected 3D box lies
      // on them within a few pixels (here within 2.1).
      EXPECT_NEAR(box->left, l.box.left, 3.0);
      EXPECT_NEAR(box->right, l.box.right, 3.0);
      EXPECT_NEAR(box->top, l.box.top, 3.0);
      EXPECT_NEAR(box->bottom, l.box.bottom, 3.0);
      ++checked;
    }
  }
  EXPECT_GE(checked, 3U);
}

TEST(KittiCamera, LidarPointsInsideALabelledBoxProjectIntoItsImageBox) {
  const Frame f = frame("000001");
  const auto scan = readKittiBin(dataDir() / "kitti_object" / "velodyne" / "000001.bin");
  ASSERT_TRUE(scan.ok());
  std::size_t inside_total = 0;
  for (const KittiLabel& l : f.labels) {
    if (l.type == "DontCare" || l.truncated > 0.0) continue;
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(l.rotation_y, Eigen::Vector3d::UnitY()).toRotationMatrix();
    std::size_t inside = 0;
    std::size_t in_image_box = 0;
    for (const Point& p : scan->points) {
      const Eigen::Vector3d rect = f.calib.velodyneToRectified(Eigen::Vector3d(p.x, p.y, p.z));
      // In the box's own frame: x along its length, y down from the bottom face, z across.
      const Eigen::Vector3d local = turn.transpose() * (rect - l.location);
      if (std::abs(local.x()) > l.size_hwl.z() / 2 || std::abs(local.z()) > l.size_hwl.y() / 2 || local.y() > 0.0 ||
          local.y() < -l.size_hwl.x()) {
        continue;
      }
      ++inside;
      const auto pixel = projectPoint(f.calib.projection[2], rect);
      if (pixel && pixel->x() >= l.box.left - 2 && pixel->x() <= l.box.right + 2 && pixel->y() >= l.box.top - 2 &&
          pixel->y() <= l.box.bottom + 2) {
        ++in_image_box;
      }
    }
    SCOPED_TRACE(l.type);
    EXPECT_GE(in_image_box * 100, inside * 95) << in_image_box << " of " << inside;
    inside_total += inside;
  }
  EXPECT_GT(inside_total, 20U) << "the labelled objects have LiDAR points";
}

TEST(KittiCamera, BrokenFilesAreErrorsNamingWhatIsWrong) {
  const auto missing = parseKittiCalibration("P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("no P1"), std::string::npos) << missing.error().message;
  const auto word = parseKittiCalibration("P0: 1 0 0 0 0 1 zero 0 0 0 1 0\n");
  ASSERT_FALSE(word.ok());
  EXPECT_NE(word.error().message.find("'zero' is not a number"), std::string::npos) << word.error().message;
  const auto short_label = parseKittiLabels("Car 0.00 0 1.85 387.63 181.54 423.81\n");
  ASSERT_FALSE(short_label.ok());
  EXPECT_NE(short_label.error().message.find("label line 1"), std::string::npos) << short_label.error().message;
  EXPECT_FALSE(projectPoint(Eigen::Matrix<double, 3, 4>::Identity(), {0, 0, -1}).has_value()) << "behind the camera";
}

// The camera a topology's detection node gets from a KITTI calib file: in the Velodyne's frame, it
// puts every LiDAR point of the bundled sequence where P2 after R0_rect and Tr_velo_to_cam does.
TEST(KittiCamera, PinholeCameraProjectsLidarPointsLikeTheProjectionMatrix) {
  const auto calib = parseKittiCalibration(slurp(dataDir() / "kitti_raw_seq_a" / "calib.txt"));
  ASSERT_TRUE(calib.ok()) << calib.error().message;
  const auto scan = readKittiBin(dataDir() / "kitti_raw_seq_a" / "0000000000.bin");
  ASSERT_TRUE(scan.ok());
  for (const int index : {2, 3}) {
    SCOPED_TRACE("camera " + std::to_string(index));
    const auto camera = pinholeCamera(*calib, index, kWidth, kHeight);
    ASSERT_TRUE(camera.ok()) << camera.error().message;
    EXPECT_EQ(camera->width, kWidth);
    EXPECT_NEAR(camera->fx, 721.5377, 1e-4);
    std::size_t in_image = 0;
    for (const Point& p : scan->points) {
      const Eigen::Vector3d point(p.x, p.y, p.z);
      const auto expected = projectPoint(calib->projection[static_cast<std::size_t>(index)], calib->velodyneToRectified(point), 1.0);
      const auto pixel = camera->project(point, 1.0);
      if (!expected) continue;
      ASSERT_TRUE(pixel.has_value());
      ASSERT_LT((*pixel - *expected).norm(), 1e-6) << point.transpose();
      if (camera->inImage(*pixel)) ++in_image;
    }
    EXPECT_GT(in_image, 5000U) << "the camera looks forward, where the scan has points";
  }
  const auto no_camera = pinholeCamera(*calib, 4, kWidth, kHeight);
  ASSERT_FALSE(no_camera.ok());
  EXPECT_NE(no_camera.error().message.find("camera 4 does not exist"), std::string::npos) << no_camera.error().message;
  KittiCalibration skewed = *calib;
  skewed.projection[2](0, 1) = 5.0;
  const auto not_pinhole = pinholeCamera(skewed, 2, kWidth, kHeight);
  ASSERT_FALSE(not_pinhole.ok());
  EXPECT_NE(not_pinhole.error().message.find("P2 is not of the form K [I | t]"), std::string::npos) << not_pinhole.error().message;
  EXPECT_FALSE(pinholeCamera(*calib, 2, 0, kHeight).ok()) << "an image without pixels";
}

// A camera at `position` looking along +x of the common frame (x right = -y, y down = -z).
PinholeCamera lookingAlongX(const Eigen::Vector3d& position, Distortion distortion = {}) {
  PinholeCamera cam;
  cam.name = "ahead";
  cam.fx = 700.0;
  cam.fy = 690.0;
  cam.cx = 620.0;
  cam.cy = 180.0;
  cam.width = 1240;
  cam.height = 375;
  cam.distortion = distortion;
  Eigen::Matrix3d r;
  r << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  cam.world_to_camera.linear() = r;
  cam.world_to_camera.translation() = -r * position;
  return cam;
}

// Brute force: the box of the projections of dense points on the ellipsoid's surface.
Box2d sampledBox(const PinholeCamera& cam, const Eigen::Vector3d& centre, const Eigen::Matrix3d& shape) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(shape);
  const Eigen::Matrix3d root = solver.eigenvectors() * solver.eigenvalues().cwiseSqrt().asDiagonal();
  Box2d box{1e18, 1e18, -1e18, -1e18};
  constexpr int kN = 720;
  for (int i = 0; i <= kN / 2; ++i) {
    const double theta = M_PI * i / (kN / 2);
    for (int j = 0; j < kN; ++j) {
      const double phi = 2.0 * M_PI * j / kN;
      const Eigen::Vector3d unit(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      const auto pixel = cam.project(centre + root * unit, 0.01);
      if (!pixel) continue;
      box.left = std::min(box.left, pixel->x());
      box.top = std::min(box.top, pixel->y());
      box.right = std::max(box.right, pixel->x());
      box.bottom = std::max(box.bottom, pixel->y());
    }
  }
  return box;
}

TEST(ProjectEllipsoid, ASphereOnTheOpticalAxisIsTheBoxOfItsTangentCone) {
  const PinholeCamera cam = lookingAlongX({0, 0, 1});
  const double d = 10.0, r = 0.5;
  const auto box = projectEllipsoid(cam, {d, 0, 1}, Eigen::Matrix3d::Identity() * r * r);
  ASSERT_TRUE(box.has_value());
  const double half = r / std::sqrt(d * d - r * r);  // tan of the cone's half angle
  EXPECT_NEAR(box->left, cam.cx - cam.fx * half, 1e-9);
  EXPECT_NEAR(box->right, cam.cx + cam.fx * half, 1e-9);
  EXPECT_NEAR(box->top, cam.cy - cam.fy * half, 1e-9);
  EXPECT_NEAR(box->bottom, cam.cy + cam.fy * half, 1e-9);
}

TEST(ProjectEllipsoid, TheBoxIsThatOfTheSurfaceProjectedPointByPointWithAndWithoutDistortion) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (const Distortion& distortion : {Distortion{}, Distortion{-0.3, 0.1, 0.001, -0.002, 0.0}}) {
    const PinholeCamera cam = lookingAlongX({0, 0, 1.5}, distortion);
    for (int k = 0; k < 20; ++k) {
      // A random ellipsoid 6 to 20 m ahead, up to 2 m across, turned anyhow.
      const Eigen::Vector3d centre(13.0 + 7.0 * unit(rng), 3.0 * unit(rng), 1.0 + 0.5 * unit(rng));
      const Eigen::Matrix3d rotation =
          Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng)).normalized()).toRotationMatrix();
      const Eigen::Vector3d axes(0.1 + std::abs(unit(rng)), 0.1 + std::abs(unit(rng)), 0.1 + std::abs(unit(rng)));
      const Eigen::Matrix3d shape = rotation * axes.cwiseAbs2().asDiagonal() * rotation.transpose();
      const auto box = projectEllipsoid(cam, centre, shape);
      ASSERT_TRUE(box.has_value()) << "ellipsoid " << k;
      const Box2d sampled = sampledBox(cam, centre, shape);
      // Dense sampling reaches the outline to a fraction of a pixel, from inside.
      const double tolerance = distortion.none() ? 0.2 : 0.5;
      EXPECT_NEAR(box->left, sampled.left, tolerance) << "ellipsoid " << k;
      EXPECT_NEAR(box->top, sampled.top, tolerance) << "ellipsoid " << k;
      EXPECT_NEAR(box->right, sampled.right, tolerance) << "ellipsoid " << k;
      EXPECT_NEAR(box->bottom, sampled.bottom, tolerance) << "ellipsoid " << k;
      if (distortion.none()) {
        EXPECT_LE(box->left, sampled.left + 1e-9);
        EXPECT_GE(box->right, sampled.right - 1e-9);
      }
    }
  }
}

TEST(ProjectEllipsoid, AnEllipsoidBehindOrAcrossTheCameraHasNoBox) {
  const PinholeCamera cam = lookingAlongX({0, 0, 1});
  EXPECT_FALSE(projectEllipsoid(cam, {-5, 0, 1}, Eigen::Matrix3d::Identity() * 0.25).has_value()) << "behind";
  EXPECT_FALSE(projectEllipsoid(cam, {0.3, 0, 1}, Eigen::Matrix3d::Identity() * 0.25).has_value()) << "around the camera";
  EXPECT_FALSE(projectEllipsoid(cam, {0.55, 0, 1}, Eigen::Matrix3d::Identity() * 0.25, 0.1).has_value())
      << "its near side 0.05 m ahead, inside near_m";
  EXPECT_TRUE(projectEllipsoid(cam, {0.65, 0, 1}, Eigen::Matrix3d::Identity() * 0.25, 0.1).has_value());
}

}  // namespace
}  // namespace fogmap::camera
