#pragma once
// Global maps made by hand for the tracker's tests: obstacles where the test puts them.
#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/geometry/map.hpp"
#include "common/io/messages.hpp"

namespace fogmap::test_support {

// A global map (epoch 1) of one obstacle per centre, at `sensor_time_ns`: each a ball of 0.3 m
// radius and 50 points from node 1, its own object with its box from the ellipsoid.
inline GlobalMapMessage globalMapWith(std::int64_t sensor_time_ns, const std::vector<Eigen::Vector3d>& centres) {
  GlobalMapMessage g;
  g.header.epoch = 1;
  g.header.sensor_time_ns = sensor_time_ns;
  std::vector<Ellipsoid> ellipsoids;
  std::uint32_t index = 0;
  for (const auto& c : centres) {
    Ellipsoid e;
    e.id = {1, 1, index++};
    e.center = c;
    e.shape = Eigen::Matrix3d::Identity() * 0.09;
    e.point_count = 50;
    ellipsoids.push_back(e);
  }
  g.map = localMap(std::move(ellipsoids));
  return g;
}

}  // namespace fogmap::test_support
