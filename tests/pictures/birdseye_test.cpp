// Bird's-eye pictures (pictures/birdseye) read back as pixels: marks land where their
// coordinates say (x right, y up, the square around the scene's center), objects in their colours,
// the legend and labels outside the map, errors that name the file, the same bytes for the same input;
// and pictures of simulated scenes (the truth under MAD-C's global objects) for a person to look at.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <numbers>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/io/cloud_io.hpp"
#include "common/perception/madc.hpp"
#include "common/geometry/map.hpp"
#include "common/perception/preprocess.hpp"
#include "common/sim/footprint.hpp"
#include "common/sim/generators.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/sim/raycaster.hpp"
#include "tests/support/scratch_dir.hpp"
#include "pictures/birdseye.hpp"

namespace fogmap::pictures {
namespace {

namespace fs = std::filesystem;

using test_support::readFile;
using test_support::ScratchDir;

Ellipsoid ellipsoid(std::uint32_t node, std::uint32_t index, Eigen::Vector3d center, Eigen::Matrix3d shape) {
  Ellipsoid e;
  e.id = {node, 1, index};
  e.center = center;
  e.shape = shape;
  e.point_count = 20;
  return e;
}

MapObject object(std::vector<Ellipsoid> ellipsoids) {
  MapObject o;
  o.ellipsoids = std::move(ellipsoids);
  return o;
}

// The pixel (column, row) that holds the common-frame point `xy`, computed here from the layout's
// map square alone: x grows to the right, y grows upwards.
cv::Point pixelOf(const BirdseyeLayout& layout, const BirdseyeScene& scene, Eigen::Vector2d xy) {
  const double px_per_m = layout.plot_size_px / (2.0 * scene.half_extent_m);
  const double col = layout.plot_left_px + (xy.x() - (scene.center.x() - scene.half_extent_m)) * px_per_m;
  const double row = layout.plot_top_px + ((scene.center.y() + scene.half_extent_m) - xy.y()) * px_per_m;
  return {static_cast<int>(std::floor(col)), static_cast<int>(std::floor(row))};
}

Rgb rgbAt(const cv::Mat& image, cv::Point p) {
  const cv::Vec3b v = image.at<cv::Vec3b>(p);
  return {v[2], v[1], v[0]};
}

// True when `image` at `p` is within `tolerance` of `colour` in every channel.
::testing::AssertionResult colourAt(const cv::Mat& image, cv::Point p, Rgb colour, int tolerance = 40) {
  const Rgb got = rgbAt(image, p);
  const bool near = std::abs(got.r - colour.r) <= tolerance && std::abs(got.g - colour.g) <= tolerance &&
                    std::abs(got.b - colour.b) <= tolerance;
  if (near) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "pixel (" << p.x << ", " << p.y << ") is (" << int(got.r) << ", " << int(got.g) << ", "
                                       << int(got.b) << "), expected about (" << int(colour.r) << ", " << int(colour.g) << ", "
                                       << int(colour.b) << ")";
}

// A scene off the origin, so a transform that forgets the center or swaps x and y puts marks elsewhere.
struct KnownScene {
  std::vector<MapObject> objects;
  Cloud points;
  BirdseyeScene scene;
  KnownScene() {
    // Object 0: an ellipse 3 m along x, 1 m along y, centred at (-6, 4).
    objects.push_back(object({ellipsoid(1, 0, {-6, 4, 0.5}, Eigen::Vector3d(9, 1, 0.25).asDiagonal())}));
    // Object 1, far away: an ellipse turned 45 degrees (semi-axes 4 and 1) at (12, -10).
    const Eigen::Matrix2d r = Eigen::Rotation2Dd(M_PI / 4).toRotationMatrix();
    Eigen::Matrix3d turned = Eigen::Matrix3d::Identity();
    turned.topLeftCorner<2, 2>() = r * Eigen::Vector2d(16, 1).asDiagonal() * r.transpose();
    objects.push_back(object({ellipsoid(2, 0, {12, -10, 0.5}, turned)}));
    for (int i = 0; i < 200; ++i) points.push_back({static_cast<float>(-15 + 0.05 * i), 15.0F, 0.2F, 0.0F});
    scene.title = "known scene";
    scene.center = {2, -1};
    scene.half_extent_m = 20.0;
    scene.points = {points};
    scene.objects = objects;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(8, 6, 1.8);
    scene.sensors = {{"lidar-a", pose, 30.0}};
    scene.truth = {{7, "crate", {{10, 10}, {14, 10}, {14, 12}, {10, 12}}}};
  }
};

TEST(Birdseye, MarksLandWhereTheirCoordinatesSayWithXRightAndYUp) {
  ScratchDir dir("marks");
  const KnownScene k;
  const fs::path png = dir.path() / "known.png";
  const Status s = drawBirdseye(png, k.scene, 800);
  ASSERT_TRUE(s.ok()) << s.error().message;
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const BirdseyeLayout layout = birdseyeLayout(k.scene, 800);
  EXPECT_EQ(image.cols, layout.width_px);
  EXPECT_EQ(image.rows, layout.height_px);
  const auto colours = birdseyeObjectColours(k.objects);
  ASSERT_EQ(colours.size(), 2U);
  EXPECT_NE(colours[0], colours[1]);

  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {8, 6}), kBirdseyeSensorColour, 10)) << "the sensor's marker";
  // Object 0's outline at the ends of its axes: 3 m along x, 1 m along y.
  for (const Eigen::Vector2d& on : {Eigen::Vector2d(-3, 4), Eigen::Vector2d(-9, 4), Eigen::Vector2d(-6, 5), Eigen::Vector2d(-6, 3)}) {
    EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, on), colours[0])) << "object 0's outline at " << on.transpose();
  }
  // Swapped axes would put the outline 3 m along y: there is only the light tint of the inside... and
  // beyond it white.
  EXPECT_FALSE(colourAt(image, pixelOf(layout, k.scene, {-6, 7}), colours[0]));
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {-6, 7.5}), kBirdseyeBackground, 0));
  // Inside: white tinted with the object's colour (neither white nor the full colour).
  const Rgb inside = rgbAt(image, pixelOf(layout, k.scene, {-7, 4.3}));
  EXPECT_NE(inside, kBirdseyeBackground);
  EXPECT_FALSE(colourAt(image, pixelOf(layout, k.scene, {-7, 4.3}), colours[0]));
  // Object 1 turned 45 degrees counter-clockwise: its major axis runs along (1, 1), not (1, -1).
  const Eigen::Vector2d c1(12, -10);
  const Eigen::Vector2d diagonal = Eigen::Vector2d(1, 1).normalized();
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, c1 + 4.0 * diagonal), colours[1]));
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, c1 - 4.0 * diagonal), colours[1]));
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, c1 + 3.0 * Eigen::Vector2d(1, -1).normalized()), kBirdseyeBackground, 0));
  // The true outline: a thin dark line along the crate's lower edge (y = 10).
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {12, 10}), kBirdseyeTruthColour, 70));
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {12, 11}), kBirdseyeBackground, 0)) << "outlines are not filled";
  // Points at y = 15 from x = -15: grey.
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {-14.5, 15.0}), kBirdseyePointColour, 0));
}

TEST(Birdseye, TheLegendLabelsAndTitleLieOutsideTheMap) {
  ScratchDir dir("legend");
  const KnownScene k;
  const fs::path png = dir.path() / "legend.png";
  ASSERT_TRUE(drawBirdseye(png, k.scene, 800).ok());
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const BirdseyeLayout layout = birdseyeLayout(k.scene, 800);
  const auto inked = [&](cv::Rect r) {
    cv::Mat grey;
    cv::cvtColor(image(r), grey, cv::COLOR_BGR2GRAY);
    return cv::countNonZero(grey < 160);  // text and dark marks
  };
  EXPECT_GT(inked({layout.legend_left_px, layout.legend_top_px, layout.legend_width_px, layout.legend_height_px}), 2000) << "the legend";
  EXPECT_GT(inked({0, 0, layout.width_px, layout.plot_top_px - 1}), 300) << "the title band";
  EXPECT_GT(inked({layout.plot_left_px, layout.plot_top_px + layout.plot_size_px + 2, layout.plot_size_px, layout.height_px - layout.plot_top_px - layout.plot_size_px - 2}),
            200)
      << "the x labels below the map";
  EXPECT_GT(inked({0, layout.plot_top_px, layout.plot_left_px - 1, layout.plot_size_px}), 200) << "the y labels left of the map";
  // The legend is beside the map, not on it.
  EXPECT_GE(layout.legend_left_px, layout.plot_left_px + layout.plot_size_px);
  // The grid: 20 m half extent gives a line every 5 m, so x = 0 (the origin, darker) is a vertical
  // line through the map and x = 2.5 is not.
  EXPECT_DOUBLE_EQ(layout.grid_m, 5.0);
  const int row = pixelOf(layout, k.scene, {0, -17}).y;
  EXPECT_LT(rgbAt(image, {pixelOf(layout, k.scene, {0, 0}).x, row}).r, 240);
  EXPECT_EQ(rgbAt(image, {pixelOf(layout, k.scene, {2.5, 0}).x, row}), kBirdseyeBackground);
}

TEST(Birdseye, TracksDrawAsMarkersWithTheirTrailsIdsAndLabels) {
  const ScratchDir scratch("tracks");
  const fs::path dir = test_support::outputDir("FOGMAP_BIRDSEYE_DIR", scratch);
  KnownScene k;
  // A confirmed track walking east along y = -8, now at (1, -8), and a lost one at (6, -14).
  k.scene.tracks = {{3, "person", {1, -8}, {{-4, -8}, {-1.5, -8}}, true}, {4, "unknown", {6, -14}, {}, false}};
  const fs::path png = dir / "known-scene-with-tracks.png";
  ASSERT_TRUE(drawBirdseye(png, k.scene, 1000).ok());
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const BirdseyeLayout layout = birdseyeLayout(k.scene, 1000);
  const Rgb walking = birdseyeTrackColour(3);
  const Rgb lost = birdseyeTrackColour(4);
  EXPECT_NE(walking, lost);
  // The marker is filled at the track's position; the trail runs through its earlier positions
  // and no further back than the oldest.
  const cv::Point at = pixelOf(layout, k.scene, {1, -8});
  EXPECT_TRUE(colourAt(image, at, walking, 10)) << "the confirmed track's marker";
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {-2.75, -8}), walking)) << "the trail between its positions";
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {-0.6, -8}), walking)) << "the trail's last leg, to the track";
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {-4.5, -8}), kBirdseyeBackground, 0)) << "nothing before the oldest position";
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, {-2.75, -7}), kBirdseyeBackground, 0)) << "the trail is a line, not a band";
  // The lost track: hollow (white inside), its outline in its colour halfway along an edge.
  const cv::Point lost_at = pixelOf(layout, k.scene, {6, -14});
  EXPECT_TRUE(colourAt(image, lost_at, kBirdseyeBackground, 0)) << "a lost track's marker is hollow";
  EXPECT_TRUE(colourAt(image, lost_at + cv::Point(3, -4), lost, 60)) << "its outline";
  // The id and label are written in the track's colour ahead of it, right of the marker (the map is
  // white there), not over its trail.
  const cv::Rect label(at.x + 8, at.y - 20, 90, 40);
  cv::Mat near_colour;
  cv::inRange(image(label), cv::Scalar(walking.b, walking.g, walking.r) - cv::Scalar::all(40),
              cv::Scalar(walking.b, walking.g, walking.r) + cv::Scalar::all(40), near_colour);
  EXPECT_GT(cv::countNonZero(near_colour), 40) << "the text '#3 person'";
  cv::Mat behind;  // above its trail, left of the marker
  cv::inRange(image(cv::Rect(at.x - 98, at.y - 20, 90, 16)), cv::Scalar(walking.b, walking.g, walking.r) - cv::Scalar::all(40),
              cv::Scalar(walking.b, walking.g, walking.r) + cv::Scalar::all(40), behind);
  EXPECT_EQ(cv::countNonZero(behind), 0) << "nothing written over the trail";
  // The legend explains them: it holds more ink than the same picture's legend without tracks.
  KnownScene bare;
  const fs::path bare_png = scratch.path() / "bare.png";
  ASSERT_TRUE(drawBirdseye(bare_png, bare.scene, 1000).ok());
  const cv::Mat without = cv::imread(bare_png.string(), cv::IMREAD_COLOR);
  const auto legend_ink = [&](const cv::Mat& m) {
    cv::Mat grey;
    cv::cvtColor(m(cv::Rect(layout.legend_left_px, layout.legend_top_px, layout.legend_width_px, layout.legend_height_px)), grey,
                 cv::COLOR_BGR2GRAY);
    return cv::countNonZero(grey < 160);
  };
  EXPECT_GT(legend_ink(image), legend_ink(without) + 300);
  EXPECT_TRUE(colourAt(without, at, kBirdseyeBackground, 0)) << "without tracks nothing is drawn there";
}

TEST(Birdseye, AVehicleTracksHeadingIsATickFromItsMarkerTheWayItsFrontPoints) {
  const ScratchDir scratch("heading");
  // One confirmed track at (1, -8) heading west (pi), and the same track without a heading.
  KnownScene with_heading;
  with_heading.scene.tracks = {{5, "car", {1, -8}, {}, true, std::numbers::pi}};
  KnownScene without;
  without.scene.tracks = {{5, "car", {1, -8}, {}, true}};
  const fs::path a = scratch.path() / "heading.png";
  const fs::path b = scratch.path() / "no-heading.png";
  ASSERT_TRUE(drawBirdseye(a, with_heading.scene, 1000).ok());
  ASSERT_TRUE(drawBirdseye(b, without.scene, 1000).ok());
  const cv::Mat image = cv::imread(a.string(), cv::IMREAD_COLOR);
  const cv::Mat bare = cv::imread(b.string(), cv::IMREAD_COLOR);
  const BirdseyeLayout layout = birdseyeLayout(with_heading.scene, 1000);
  const cv::Point at = pixelOf(layout, with_heading.scene, {1, -8});
  // The marker's radius is 7 px at this size and the tick 2.5 radii long: 14 px west of the centre
  // lies on the tick, in the track's colour; without a heading that pixel is the map's background.
  const cv::Point west = at + cv::Point(-14, 0);
  EXPECT_TRUE(colourAt(image, west, birdseyeTrackColour(5), 60)) << "the tick, west of the marker";
  EXPECT_TRUE(colourAt(bare, west, kBirdseyeBackground, 0)) << "no tick without a heading";
  EXPECT_TRUE(colourAt(image, at + cv::Point(-14, 8), kBirdseyeBackground, 0)) << "a tick, not a band";
}

TEST(Birdseye, TrackLabelsDoNotCoverEachOther) {
  ScratchDir dir("labels");
  KnownScene k;
  // Two tracks in one place with no trail: the first one's label takes the right of the marker,
  // the second's the first side that does not touch it (above and below reach under the first).
  k.scene.tracks = {{3, "person", {1, -8}, {}, true}, {4, "person", {1, -8}, {}, true}};
  const fs::path png = dir.path() / "labels.png";
  ASSERT_TRUE(drawBirdseye(png, k.scene, 1000).ok());
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const cv::Point at = pixelOf(birdseyeLayout(k.scene, 1000), k.scene, {1, -8});
  const auto inColour = [&](cv::Rect r, Rgb c) {
    cv::Mat mask;
    cv::inRange(image(r), cv::Scalar(c.b, c.g, c.r) - cv::Scalar::all(40), cv::Scalar(c.b, c.g, c.r) + cv::Scalar::all(40), mask);
    return cv::countNonZero(mask);
  };
  const cv::Rect right(at.x + 10, at.y - 12, 90, 24);
  const cv::Rect left(at.x - 100, at.y - 12, 90, 24);
  EXPECT_GT(inColour(right, birdseyeTrackColour(3)), 40);
  EXPECT_EQ(inColour(right, birdseyeTrackColour(4)), 0);
  EXPECT_GT(inColour(left, birdseyeTrackColour(4)), 40);
  EXPECT_EQ(inColour(left, birdseyeTrackColour(3)), 0);
}

// How many pixels of `r` are within `tolerance` of `colour` in every channel.
int pixelsNear(const cv::Mat& image, cv::Rect r, Rgb colour, int tolerance) {
  cv::Mat mask;
  cv::inRange(image(r), cv::Scalar(colour.b, colour.g, colour.r) - cv::Scalar::all(tolerance),
              cv::Scalar(colour.b, colour.g, colour.r) + cv::Scalar::all(tolerance), mask);
  return cv::countNonZero(mask);
}

TEST(Birdseye, MissedObjectsAreMarkedAtTheirCentresAndNowhereElse) {
  const ScratchDir scratch("missed");
  const fs::path dir = test_support::outputDir("FOGMAP_BIRDSEYE_DIR", scratch);
  KnownScene k;
  // One missed object in an empty place, one on the crate's outline (marks go over the truth).
  const Eigen::Vector2d empty_place(-2, -12);
  const Eigen::Vector2d on_crate(12, 11);
  k.scene.missed = std::vector<Eigen::Vector2d>{empty_place, on_crate};
  const fs::path png = dir / "known-scene-with-missed-objects.png";
  ASSERT_TRUE(drawBirdseye(png, k.scene, 1000).ok());
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const BirdseyeLayout layout = birdseyeLayout(k.scene, 1000);
  const cv::Rect map(layout.plot_left_px, layout.plot_top_px, layout.plot_size_px, layout.plot_size_px);
  const cv::Rect legend(layout.legend_left_px, layout.legend_top_px, layout.legend_width_px, layout.legend_height_px);
  constexpr int kTolerance = 30;  // the palette's red (214, 39, 40) is further than this from the mark's
  const auto around = [&](const Eigen::Vector2d& xy) {
    const cv::Point at = pixelOf(layout, k.scene, xy);
    return cv::Rect(at.x - 16, at.y - 16, 33, 33);
  };
  for (const Eigen::Vector2d& xy : {empty_place, on_crate}) {
    const cv::Point at = pixelOf(layout, k.scene, xy);
    EXPECT_TRUE(colourAt(image, at, kBirdseyeMissedColour, kTolerance)) << "the cross through " << xy.transpose();
    EXPECT_GT(pixelsNear(image, around(xy), kBirdseyeMissedColour, kTolerance), 80) << "the ring and cross at " << xy.transpose();
  }
  // The ring (10 px across at this size) is hollow between the cross's arms: right of the centre is white.
  EXPECT_TRUE(colourAt(image, pixelOf(layout, k.scene, empty_place) + cv::Point(6, 0), kBirdseyeBackground, 0));
  // Nothing of the mark's colour on the map but the two marks.
  EXPECT_EQ(pixelsNear(image, map, kBirdseyeMissedColour, kTolerance),
            pixelsNear(image, around(empty_place), kBirdseyeMissedColour, kTolerance) +
                pixelsNear(image, around(on_crate), kBirdseyeMissedColour, kTolerance));
  EXPECT_GT(pixelsNear(image, legend, kBirdseyeMissedColour, kTolerance), 20) << "the legend's \"missed\" entry";

  // Scored with nothing missed: no mark on the map, the legend's entry still there (saying none).
  k.scene.missed = std::vector<Eigen::Vector2d>{};
  ASSERT_TRUE(drawBirdseye(dir / "none-missed.png", k.scene, 1000).ok());
  const cv::Mat none = cv::imread((dir / "none-missed.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(none.empty());
  EXPECT_EQ(pixelsNear(none, map, kBirdseyeMissedColour, kTolerance), 0);
  EXPECT_TRUE(colourAt(none, pixelOf(layout, k.scene, empty_place), kBirdseyeBackground, 0));
  EXPECT_GT(pixelsNear(none, legend, kBirdseyeMissedColour, kTolerance), 20);
  // Not scored: neither mark nor entry.
  k.scene.missed.reset();
  ASSERT_TRUE(drawBirdseye(dir / "not-scored.png", k.scene, 1000).ok());
  const cv::Mat unscored = cv::imread((dir / "not-scored.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(unscored.empty());
  EXPECT_EQ(pixelsNear(unscored, map, kBirdseyeMissedColour, kTolerance), 0);
  EXPECT_EQ(pixelsNear(unscored, legend, kBirdseyeMissedColour, kTolerance), 0);
}

TEST(Birdseye, AnUnwritablePathIsAnErrorThatNamesIt) {
  const KnownScene k;
  const fs::path png = "/nonexistent-birdseye-dir/deeper/map.png";
  const Status s = drawBirdseye(png, k.scene, 400);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kIo);
  EXPECT_NE(s.error().message.find(png.string()), std::string::npos) << s.error().message;
}

TEST(Birdseye, ABadExtentOrSizeIsRejected) {
  ScratchDir dir("bad");
  KnownScene k;
  k.scene.half_extent_m = 0.0;
  EXPECT_EQ(drawBirdseye(dir.path() / "a.png", k.scene).error().code, ErrorCode::kInvalidArgument);
  k.scene.half_extent_m = std::nan("");
  EXPECT_EQ(drawBirdseye(dir.path() / "b.png", k.scene).error().code, ErrorCode::kInvalidArgument);
  k.scene.half_extent_m = 10.0;
  EXPECT_EQ(drawBirdseye(dir.path() / "c.png", k.scene, 50).error().code, ErrorCode::kInvalidArgument);
  EXPECT_FALSE(fs::exists(dir.path() / "c.png"));
}

TEST(Birdseye, TheSameInputGivesTheSameBytes) {
  ScratchDir dir("same");
  KnownScene k;
  ASSERT_TRUE(drawBirdseye(dir.path() / "one.png", k.scene, 600).ok());
  ASSERT_TRUE(drawBirdseye(dir.path() / "two.png", k.scene, 600).ok());
  const std::string one = readFile(dir.path() / "one.png");
  EXPECT_GT(one.size(), 1000U);
  EXPECT_EQ(one, readFile(dir.path() / "two.png"));
  k.scene.sensors[0].pose.translation().x() += 1.0;
  ASSERT_TRUE(drawBirdseye(dir.path() / "three.png", k.scene, 600).ok());
  EXPECT_NE(one, readFile(dir.path() / "three.png")) << "a moved sensor changes the picture";
}

TEST(Birdseye, NeighbouringObjectsGetDifferentColours) {
  // Nine small objects in a 3 x 3 block 1 m apart: all neighbours, so all nine palette colours.
  std::vector<MapObject> block;
  for (std::uint32_t i = 0; i < 9; ++i) {
    block.push_back(object({ellipsoid(1, i, {1.0 * (i % 3), 1.0 * (i / 3), 0}, 0.04 * Eigen::Matrix3d::Identity())}));
  }
  const auto colours = birdseyeObjectColours(block);
  for (std::size_t a = 0; a < colours.size(); ++a) {
    for (std::size_t b = a + 1; b < colours.size(); ++b) EXPECT_NE(colours[a], colours[b]) << a << " and " << b;
  }
  // An object far from all of them, tenth in line, takes the palette's first colour again.
  block.push_back(object({ellipsoid(2, 0, {100, 100, 0}, Eigen::Matrix3d::Identity())}));
  EXPECT_EQ(birdseyeObjectColours(block).back(), kBirdseyePalette[0]);
  // Next to object 0 instead, it may not take object 0's colour.
  block.back() = object({ellipsoid(2, 0, {-1.5, 0, 0}, 0.04 * Eigen::Matrix3d::Identity())});
  EXPECT_NE(birdseyeObjectColours(block).back(), birdseyeObjectColours(block).front());
  EXPECT_EQ(birdseyeObjectColours(block), birdseyeObjectColours(block)) << "deterministic";
}

// A simulated scene at `time_s`, as a fog cluster of its LiDARs would see it: every LiDAR's frame in
// the common frame with the ground dropped (by the truth), MAD-C local maps merged into the global map.
struct SimulatedMap {
  std::vector<Cloud> clouds;
  Map global;
  std::vector<BirdseyeSensor> sensors;
  std::vector<BirdseyeOutline> truth;
};

SimulatedMap simulate(const sim::Scene& scene, double time_s) {
  SimulatedMap out;
  auto raycaster = sim::SceneRaycaster::build(scene, time_s);
  EXPECT_TRUE(raycaster.ok());
  if (!raycaster.ok()) return out;
  std::vector<Map> locals;
  for (std::size_t n = 0; n < scene.lidars.size(); ++n) {
    const sim::LidarConfig& lidar = scene.lidars[n];
    const auto frame = raycaster->scan(lidar, scene.seed, 0, 2);
    EXPECT_TRUE(frame.ok());
    if (!frame.ok()) continue;
    const Cloud in_common = transformCloud(frame->points, lidar.pose);
    Cloud objects;
    for (std::size_t i = 0; i < in_common.size(); ++i) {
      if (frame->truth[i] != sim::kGroundId) objects.push_back(in_common[i]);
    }
    locals.push_back(genLocalMap(objects, static_cast<std::uint32_t>(n + 1), 0, MadcParams{}).value().map);
    out.clouds.push_back(std::move(objects));
    const auto model = lidarModel(lidar.model);
    out.sensors.push_back({lidar.name, lidar.pose, lidar.max_range_m.value_or(model.ok() ? model->max_range_m : 0.0)});
  }
  out.global = mergeAll(locals).map;
  for (const auto& o : scene.objects) out.truth.push_back({o.id, o.label, sim::footprint(o, time_s)});
  return out;
}

// The distance from `p` to the closed polygon `polygon` (0 inside).
double distanceToPolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p) {
  bool inside = false;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const auto& a = polygon[i];
    const auto& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) inside = !inside;
    const Eigen::Vector2d ab = b - a;
    const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-18), 0.0, 1.0);
    nearest = std::min(nearest, (a + t * ab - p).norm());
  }
  return inside ? 0.0 : nearest;
}

// Draws a simulated scene and checks the truth and the global map agree in the picture's frame: every
// ellipsoid stands on a true footprint (a cluster of one visible face has its centre on the outline,
// give or take the range noise). The pictures go to $FOGMAP_BIRDSEYE_DIR when set.
void drawSimulated(const sim::Scene& scene, double time_s, double half_extent_m, const std::string& file) {
  const SimulatedMap m = simulate(scene, time_s);
  ASSERT_FALSE(m.global.objects.empty());
  for (const auto& o : m.global.objects) {
    for (const auto& e : o.ellipsoids) {
      const bool on_truth = std::any_of(m.truth.begin(), m.truth.end(), [&](const BirdseyeOutline& t) {
        return distanceToPolygon(t.polygon, e.center.head<2>()) < 0.1;
      });
      EXPECT_TRUE(on_truth) << "ellipsoid " << toString(e.id) << " at " << e.center.transpose() << " stands on no true object";
    }
  }
  BirdseyeScene picture;
  char title[160];
  std::snprintf(title, sizeof(title), "MAD-C global map of simulated scene %s at t = %.1f s: %zu objects (%zu true)", scene.name.c_str(),
                time_s, m.global.objects.size(), scene.objects.size());
  picture.title = title;
  picture.half_extent_m = half_extent_m;
  for (const auto& c : m.clouds) picture.points.emplace_back(c);
  picture.objects = m.global.objects;
  picture.sensors = m.sensors;
  picture.truth = m.truth;
  const ScratchDir scratch("sim");
  const fs::path dir = test_support::outputDir("FOGMAP_BIRDSEYE_DIR", scratch);
  const Status s = drawBirdseye(dir / file, picture);
  ASSERT_TRUE(s.ok()) << s.error().message;
  const cv::Mat image = cv::imread((dir / file).string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, birdseyeLayout(picture, 1000).width_px);
  std::printf("bird's-eye view: %s\n", (dir / file).c_str());
}

TEST(Birdseye, ARandomSceneDrawsItsGlobalObjectsOnTheirTrueOutlines) {
  drawSimulated(sim::randomScene(50, 5, 1), 0.0, 30.0, "random-50-lidars-5-seed-1.png");
}

TEST(Birdseye, AFactoryDrawsItsMovingForkliftsWhereTheyAreAtTheTime) {
  sim::Scene factory = sim::factoryScene(1);
  for (auto& lidar : factory.lidars) lidar.max_range_m = 25.0;  // short ranges: their circles cross the hall
  drawSimulated(factory, 2.0, 22.5, "factory-seed-1-t2s.png");
}

// Real data has no truth: one KITTI scan, pre-processed as an edge does, its MAD-C local map.
TEST(Birdseye, ARealScanDrawsWithoutTruth) {
  const fs::path scan = fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a" / "0000000000.bin";
  if (!fs::exists(scan)) GTEST_SKIP() << "no bundled scan at " << scan;
  const auto loaded = readKittiBin(scan);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  PreprocessConfig config;
  config.crop = CropBox{{-40.0, -40.0, -3.0}, {40.0, 40.0, 3.0}};
  config.ground = GroundParams{};
  const auto points = preprocess(loaded->points, config);
  ASSERT_TRUE(points.ok()) << points.error().message;
  const Map map = genLocalMap(*points, 1, 0, MadcParams{}).value().map;
  ASSERT_FALSE(map.objects.empty());
  BirdseyeScene picture;
  picture.title = "KITTI raw scan 0000000000, ground removed: MAD-C local map, " + std::to_string(map.objects.size()) + " objects";
  picture.half_extent_m = 40.0;
  picture.points = {*points};
  picture.objects = map.objects;
  picture.sensors = {{"velodyne (HDL-64E)", Eigen::Isometry3d::Identity(), 120.0}};
  const ScratchDir scratch("kitti");
  const fs::path dir = test_support::outputDir("FOGMAP_BIRDSEYE_DIR", scratch);
  const fs::path png = dir / "kitti-raw-seq-a-scan-0.png";
  const Status s = drawBirdseye(png, picture);
  ASSERT_TRUE(s.ok()) << s.error().message;
  const cv::Mat image = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_TRUE(colourAt(image, pixelOf(birdseyeLayout(picture, 1000), picture, {0, 0}), kBirdseyeSensorColour, 10));
  std::printf("bird's-eye view: %s\n", png.c_str());
}

}  // namespace
}  // namespace fogmap::pictures
