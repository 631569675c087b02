#pragma once
// Scenes made from a seed: random objects on an area (the MAD-C paper's evaluation scenes), a
// factory, and moving people and vehicles for tracking. Same arguments, same scene.
#include <cstdint>

#include "common/sim/scene.hpp"

namespace fogmap::sim {

// The paper's LiDAR spots Lambda_1 .. Lambda_7 around a square area of half-size `half_m`: the
// corners first, then the middles of two sides, then the centre; 1.8 m up, facing the centre.
std::vector<LidarConfig> lidarSpots(int count, double half_m, const std::string& model);

// N objects from 0.8 m crates to trucks, people and poles, placed at random without touching
// (gaps of at least 1 m) on a 50 x 50 m area, each turned at random about its vertical axis; K
// LiDARs (HDL-32E, as in the paper) at lidarSpots(K).
Scene randomScene(int objects, int lidars, std::uint64_t seed);
// A factory hall: LiDARs in the four corners and the middle, rows of shelves, forklifts driving
// along the aisles, people walking, a crane.
Scene factoryScene(std::uint64_t seed);
// People and vehicles on crossing and parallel straight paths across a 40 x 40 m area, each going
// back and forth from a drawn point of its path in a drawn direction; K static LiDARs and C
// cameras around it looking inwards. Vehicles keep to lanes: parallel vehicle paths lie at least
// 3 m apart (offsets drawn again, at most 64 times each). Nothing passes through anything: over
// the scene's cycle (checked every 0.02 s) no two bodies come closer than 0.5 m, two vehicles 1 m
// (footprintGap); an object's path, start and direction are drawn again, at most 256 times (4,096
// in a scene), and the draw that falls short at the fewest instants stays when none keeps enough.
// Vehicles are placed first, all at one speed drawn per scene.
Scene movingScene(int people, int vehicles, int lidars, int cameras, std::uint64_t seed);

// A camera pose at `position` looking at `target` (x right, y down, z forward; the image's up is
// the scene's +z).
Eigen::Isometry3d lookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target);

}  // namespace fogmap::sim
