#pragma once
// Bird's-eye pictures of a global map a person can read: LiDAR points, every global object's
// ellipsoids as ellipses in the object's colour and its oriented box (when the edges fit boxes) in
// its class's colour, sensors with their range, true object outlines when known, the true objects
// that were missed when scored, tracks with their ids, labels and trails when given, a metre grid, a
// scale bar, a legend and a title. A pure drawing unit: no sockets.
//
// The picture: a title band on top, then the square map (x right, y up, in the common frame) with
// its grid labelled in metres on the left and bottom edges, and the legend in a panel on its right,
// so no text lies on the data except the sensors' names.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"
#include "common/geometry/ellipsoid.hpp"
#include "common/geometry/map.hpp"

namespace fogmap::pictures {

struct BirdseyeSensor {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // sensor -> common frame
  double range_m = 0.0;  // drawn as a faint circle (LiDARs see 360 degrees); 0: no circle
};

// A true object's footprint on the ground (sim::footprint), common frame.
struct BirdseyeOutline {
  std::uint32_t id = 0;
  std::string label;
  std::vector<Eigen::Vector2d> polygon;
};

// A track (a tracker's estimate of a moving object) where it is, with the positions it had before.
struct BirdseyeTrack {
  std::uint64_t id = 0;
  std::string label;                    // what the cameras named it ("unknown" until one did)
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // common frame
  std::vector<Eigen::Vector2d> trail;   // its earlier positions, oldest first
  bool confirmed = true;                // else lost (coasting on its motion model): drawn hollow
  std::optional<double> heading_rad{};  // a vehicle's: a tick from its marker the way its front points
};

// What to draw. Points and objects are views: what they refer to must outlive drawBirdseye.
struct BirdseyeScene {
  std::string title;  // e.g. "MAD-C global map, epoch 123: 48 objects"
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // of the square shown, common frame
  double half_extent_m = 40.0;                       // the square reaches this far from center in x and y
  std::vector<std::span<const Point>> points;        // any number of clouds, common frame; drawn small and grey
  std::span<const MapObject> objects;                // each object's ellipsoids: the x-y marginal ellipse of each
  std::vector<BirdseyeSensor> sensors;
  std::vector<BirdseyeOutline> truth;                // may be empty (real data has no truth)
  // Drawn over everything but the sensors; a track's "#id label" goes on a side of its marker where
  // it covers no other track's (confirmed tracks first), and is left out where there is none.
  std::vector<BirdseyeTrack> tracks;
  // The centres of the true objects the clustering missed (e.g. from matchEachObject), common
  // frame: each drawn as a ring with a cross in kBirdseyeMissedColour over the map, with a legend
  // entry "missed". None: not scored (no mark, no entry); empty: scored, none missed (the entry says so).
  std::optional<std::vector<Eigen::Vector2d>> missed;
};

struct Rgb {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
  bool operator==(const Rgb&) const = default;
};

// The colours a picture uses; an object's colour is one of kBirdseyePalette.
inline constexpr Rgb kBirdseyeBackground{255, 255, 255};
inline constexpr Rgb kBirdseyePointColour{150, 150, 150};
inline constexpr Rgb kBirdseyeSensorColour{0, 0, 0};
inline constexpr Rgb kBirdseyeTruthColour{70, 70, 70};
// A pure red, apart from the palette's brick red (214, 39, 40) by 39 and 40 in green and blue.
inline constexpr Rgb kBirdseyeMissedColour{255, 0, 0};
inline constexpr Rgb kBirdseyePalette[] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44},  {214, 39, 40}, {148, 103, 189},
                                           {140, 86, 75},  {227, 119, 194}, {188, 189, 34}, {23, 190, 207}};

// Oriented boxes (objectBox) are outlined in their object's class colour (objectLabel), indexed by
// ObjectClass: other, person, car, truck or bus, cyclist, pole; without a class in black.
inline constexpr Rgb kBirdseyeClassPalette[] = {{110, 110, 110}, {220, 20, 60}, {0, 70, 200},
                                                {0, 130, 130},   {230, 140, 0}, {120, 60, 160}};
inline constexpr Rgb kBirdseyeUnclassifiedColour{0, 0, 0};
Rgb birdseyeClassColour(std::optional<ObjectClass> object_class);

// Tracks are drawn in these colours, darker than the objects' so that a track stands out on its object.
inline constexpr Rgb kBirdseyeTrackPalette[] = {{190, 0, 120}, {0, 105, 60}, {170, 70, 0}, {60, 40, 190}, {0, 110, 140}, {120, 30, 30}};

// Where the parts of a picture lie, in pixels from the top-left corner.
struct BirdseyeLayout {
  int width_px = 0;
  int height_px = 0;
  int plot_left_px = 0;  // the map: a square of plot_size_px, the scene's square
  int plot_top_px = 0;
  int plot_size_px = 0;
  int legend_left_px = 0;  // the legend panel, right of the map
  int legend_top_px = 0;
  int legend_width_px = 0;
  int legend_height_px = 0;
  double grid_m = 0.0;  // spacing of the labelled grid lines (also the scale bar's length)
};

// The layout of a picture whose map is `size_px` square; fixed by size_px and the extent alone.
BirdseyeLayout birdseyeLayout(const BirdseyeScene& scene, int size_px);

// Each object's colour, in the order of `objects`: deterministic, and objects close to each other
// get different colours where the palette allows.
std::vector<Rgb> birdseyeObjectColours(std::span<const MapObject> objects);

// A track's colour: one of kBirdseyeTrackPalette, by its id.
Rgb birdseyeTrackColour(std::uint64_t id);

// Draws `scene` into a PNG file at `png` (PNG whatever the extension); the map is size_px square
// (in [200, 8000]), the whole picture larger (birdseyeLayout). The same input gives the same bytes.
// Errors: an invalid extent or size (kInvalidArgument); the file cannot be written (kIo, naming it).
Status drawBirdseye(const std::filesystem::path& png, const BirdseyeScene& scene, int size_px = 1000);

}  // namespace fogmap::pictures
