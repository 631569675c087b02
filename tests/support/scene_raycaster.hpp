#pragma once
// The simulator's raycaster for the scene tests, built or the test failed.
#include <utility>

#include <gtest/gtest.h>

#include "common/sim/raycaster.hpp"
#include "common/sim/scene.hpp"

namespace fogmap::test_support {

// The raycaster of `scene` with its objects where they are at time `t` s; a build error fails the
// test with its message.
inline sim::SceneRaycaster raycaster(const sim::Scene& scene, double t = 0.0) {
  auto r = sim::SceneRaycaster::build(scene, t);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
  return std::move(r).value();
}

}  // namespace fogmap::test_support
