#pragma once
// Global assignment of tracks to measurements (the Hungarian method, Kuhn-Munkres with potentials,
// O(n^2 m) per connected component of the finite pairs): the matching of least total cost, where a
// pair whose cost is infinite (outside the gate) is never matched. Pure; the tracker's associate step.
#include <cstddef>
#include <optional>
#include <vector>

namespace fogmap::tracking {

// cost[r][c]: the cost of giving row r (a track) column c (a measurement); +infinity where they may
// not be matched. All rows have the same length. Returns, per row, its column or nothing; among
// the matchings with the most pairs it has the least total cost.
std::vector<std::optional<std::size_t>> assignMinCost(const std::vector<std::vector<double>>& cost);

}  // namespace fogmap::tracking
