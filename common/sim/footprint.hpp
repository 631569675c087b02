#pragma once
// The ground-plane outline of a simulated object: what a bird's-eye view draws as its truth.
#include <span>
#include <vector>

#include <Eigen/Core>

#include "common/sim/scene.hpp"

namespace fogmap::sim {

// Sides of the polygon that stands for a cylinder (vertices on its circle).
inline constexpr int kFootprintCylinderSides = 16;

// The object's outline on the ground at `time_s` (where poseAt puts it): the convex hull of its
// parts' outlines (boxes as rotated rectangles, cylinders as 16-gons with vertices on the circle),
// counter-clockwise from the lowest x (then lowest y), without collinear points or a repeated
// first vertex. Composites (a forklift, a car with its cabin) become one hull; no parts, no polygon.
std::vector<Eigen::Vector2d> footprint(const SceneObject& object, double time_s);

// How far apart two convex outlines (footprint's) are: the largest gap between their projections
// on a normal of one of their sides or on the line between their centroids; negative when they
// overlap. A lower bound on the distance between them, exact where a side of one faces the other.
// Empty outlines are infinitely far from anything.
double footprintGap(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b);

// The convex hull of `points`, counter-clockwise from the lowest x (then lowest y), collinear
// points dropped; fewer than 3 distinct points come back as they are (deduplicated and sorted).
std::vector<Eigen::Vector2d> convexHull(std::vector<Eigen::Vector2d> points);

}  // namespace fogmap::sim
