#include "common/tracking/assignment.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <utility>

namespace fogmap::tracking {

namespace {

std::vector<std::optional<std::size_t>> assignDense(const std::vector<std::vector<double>>& cost) {
  const std::size_t rows = cost.size();
  std::vector<std::optional<std::size_t>> out(rows);
  if (rows == 0) return out;
  const std::size_t cols = cost[0].size();
  if (cols == 0) return out;
  // A square problem of size n = rows + cols: forbidden pairs cost `big`, and every row and column
  // may stay unmatched through a dummy partner at cost `skip`. With big > the cost of any matching
  // of finite pairs and skip chosen so that one more real pair always beats leaving two unmatched,
  // the optimum has the most finite pairs and, among those, the least cost.
  double finite_max = 0.0;
  for (const auto& row : cost) {
    for (const double c : row) {
      if (std::isfinite(c)) finite_max = std::max(finite_max, std::abs(c));
    }
  }
  const std::size_t n = rows + cols;
  const double skip = (finite_max + 1.0) * static_cast<double>(n);  // two skips outweigh any pair
  const double big = 4.0 * skip * static_cast<double>(n);            // never better than skipping
  const auto at = [&](std::size_t r, std::size_t c) -> double {
    if (r < rows && c < cols) return std::isfinite(cost[r][c]) ? cost[r][c] : big;
    if (r < rows || c < cols) return skip;  // a row or a column left alone
    return 0.0;                             // dummy with dummy
  };
  // Kuhn-Munkres with potentials (1-based arrays; p[j] is the row given column j).
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(n + 1, 0.0), v(n + 1, 0.0);
  std::vector<std::size_t> p(n + 1, 0), way(n + 1, 0);
  for (std::size_t i = 1; i <= n; ++i) {
    p[0] = i;
    std::size_t j0 = 0;
    std::vector<double> minv(n + 1, inf);
    std::vector<char> used(n + 1, 0);
    do {
      used[j0] = 1;
      const std::size_t i0 = p[j0];
      double delta = inf;
      std::size_t j1 = 0;
      for (std::size_t j = 1; j <= n; ++j) {
        if (used[j]) continue;
        const double reduced = at(i0 - 1, j - 1) - u[i0] - v[j];
        if (reduced < minv[j]) {
          minv[j] = reduced;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      for (std::size_t j = 0; j <= n; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const std::size_t j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  for (std::size_t j = 1; j <= n; ++j) {
    const std::size_t r = p[j] - 1;
    const std::size_t c = j - 1;
    if (r < rows && c < cols && std::isfinite(cost[r][c])) out[r] = c;
  }
  return out;
}

}  // namespace

std::vector<std::optional<std::size_t>> assignMinCost(const std::vector<std::vector<double>>& cost) {
  const std::size_t rows = cost.size();
  std::vector<std::optional<std::size_t>> out(rows);
  if (rows == 0 || cost[0].empty()) return out;
  const std::size_t cols = cost[0].size();
  // No finite pair joins two connected components of the gate graph (rows and columns linked by
  // their finite costs), so the best matching is the best matching of each component: solved one
  // by one, the cubic method pays for the largest component, not for every track and measurement
  // at once (the same optimum; among equal ones the choice may differ).
  std::vector<std::size_t> parent(rows + cols);
  std::iota(parent.begin(), parent.end(), 0);
  const auto root = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t c = 0; c < cols; ++c) {
      if (std::isfinite(cost[r][c])) parent[root(r)] = root(rows + c);
    }
  }
  std::map<std::size_t, std::pair<std::vector<std::size_t>, std::vector<std::size_t>>> components;
  for (std::size_t r = 0; r < rows; ++r) components[root(r)].first.push_back(r);
  for (std::size_t c = 0; c < cols; ++c) components[root(rows + c)].second.push_back(c);
  for (const auto& [id, members] : components) {
    const auto& [in_rows, in_cols] = members;
    if (in_rows.empty() || in_cols.empty()) continue;  // nothing to match
    std::vector<std::vector<double>> part(in_rows.size(), std::vector<double>(in_cols.size()));
    for (std::size_t r = 0; r < in_rows.size(); ++r) {
      for (std::size_t c = 0; c < in_cols.size(); ++c) part[r][c] = cost[in_rows[r]][in_cols[c]];
    }
    const auto matched = assignDense(part);
    for (std::size_t r = 0; r < in_rows.size(); ++r) {
      if (matched[r]) out[in_rows[r]] = in_cols[*matched[r]];
    }
  }
  return out;
}

}  // namespace fogmap::tracking
