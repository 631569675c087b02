#pragma once
// The headers that the pure libraries under common/ with Eigen at their heart parse in every unit
// (geometry, perception, tracking, sim, config, camera, classify) and the cores built on them (the
// edge's, the aggregator's, the pictures), precompiled once and reused by those targets
// (cmake/fogmap_helpers.cmake, fogmap_use_pch). A source still includes what it uses.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
