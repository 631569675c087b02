#include "common/geometry/map.hpp"

#include <algorithm>
#include <array>
#include <limits>
#include <map>
#include <numeric>

namespace fogmap {

DisjointSets::DisjointSets(std::size_t n) { reset(n); }

void DisjointSets::reset(std::size_t n) {
  parent_.resize(n);
  std::iota(parent_.begin(), parent_.end(), 0U);
  rank_.assign(n, 0);
}

std::size_t DisjointSets::find(std::size_t x) {
  std::size_t root = x;
  while (parent_[root] != root) root = parent_[root];
  while (parent_[x] != root) {  // path compression
    const std::size_t next = parent_[x];
    parent_[x] = static_cast<std::uint32_t>(root);
    x = next;
  }
  return root;
}

bool DisjointSets::unite(std::size_t x, std::size_t y) {
  x = find(x);
  y = find(y);
  if (x == y) return false;
  if (rank_[x] < rank_[y]) std::swap(x, y);  // union by rank
  parent_[y] = static_cast<std::uint32_t>(x);
  if (rank_[x] == rank_[y]) ++rank_[x];
  return true;
}

std::size_t Map::ellipsoidCount() const {
  std::size_t n = 0;
  for (const auto& o : objects) n += o.ellipsoids.size();
  return n;
}

std::uint64_t MapObject::pointCount() const {
  std::uint64_t n = 0;
  for (const auto& e : ellipsoids) n += e.point_count;
  return n;
}

Map withoutFragments(const Map& merged, std::uint64_t min_points) {
  Map out;
  out.objects.reserve(merged.objects.size());
  for (const auto& object : merged.objects) {
    if (object.pointCount() >= min_points) out.objects.push_back(object);
  }
  return out;
}

Map mapFromGroups(std::span<const Ellipsoid> ellipsoids, std::span<const std::size_t> object_of) {
  std::vector<std::size_t> order(ellipsoids.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ellipsoids[a].id < ellipsoids[b].id; });
  // Walking ellipsoids in id order makes each object's first ellipsoid its smallest id, and
  // objects appear in the order of their smallest ids: the canonical form.
  Map map;
  std::vector<std::size_t> object_slot(ellipsoids.size(), SIZE_MAX);
  for (const auto i : order) {
    auto& slot = object_slot[object_of[i]];
    if (slot == SIZE_MAX) {
      slot = map.objects.size();
      map.objects.emplace_back();
    }
    auto& object = map.objects[slot];
    object.ellipsoids.push_back(ellipsoids[i]);
    object.box.extend(delimitingBox(ellipsoids[i]));
  }
  return map;
}

Map localMap(std::vector<Ellipsoid> ellipsoids) {
  std::vector<std::size_t> object_of(ellipsoids.size());
  std::iota(object_of.begin(), object_of.end(), 0);
  return mapFromGroups(ellipsoids, object_of);
}

namespace {

// The exact test counts ellipsoids as touching up to a relative tolerance of 1e-9 on the
// separating function: it accepts pairs whose shapes grown by 1 + 1e-9 (semi-axes by about
// 1 + 5e-10) meet, so their delimiting boxes may be apart by that much. Pruning must never drop
// a pair the exact test accepts: boxes grow by far more than that tolerance, which also covers
// the rounding of the exact test, yet by so little that they prune as many pairs as before.
constexpr double kPruningGrowth = 1e-6;

// The delimiting box grown so that box pruning is conservative with respect to the exact test:
// by kPruningGrowth of each half extent, plus a few ulps of the coordinates for the rounding of
// centre +- half extent (the exact test works on the centres' difference).
Box pruningBox(const Ellipsoid& e) {
  const Box box = delimitingBox(e);
  const Eigen::Vector3d half = 0.5 * (box.max - box.min);
  const Eigen::Vector3d margin =
      kPruningGrowth * half + 4.0 * std::numeric_limits<double>::epsilon() * (e.center.cwiseAbs() + half);
  return Box{box.min - margin, box.max + margin};
}

// One ellipsoid of a MERGE: its box for pruning and the input map it came from.
struct Item {
  const Ellipsoid* ellipsoid;
  Box box;
  std::size_t map;
};

}  // namespace

MergeResult mergeMaps(std::span<const Map* const> maps) {
  MergeResult result;
  std::size_t total = 0;
  for (const auto* m : maps) total += m->ellipsoidCount();

  // Deduplicate by id: an ellipsoid seen in several maps (a re-sent or overlapping input) is one
  // item; every map's grouping still applies to it.
  std::vector<std::pair<EllipsoidId, std::size_t>> by_id;  // (id, position in input order)
  by_id.reserve(total);
  std::vector<const Ellipsoid*> input;
  std::vector<std::size_t> input_map;
  input.reserve(total);
  input_map.reserve(total);
  for (std::size_t m = 0; m < maps.size(); ++m) {
    for (const auto& object : maps[m]->objects) {
      for (const auto& e : object.ellipsoids) {
        by_id.emplace_back(e.id, input.size());
        input.push_back(&e);
        input_map.push_back(m);
      }
    }
  }
  std::sort(by_id.begin(), by_id.end());
  std::vector<std::size_t> item_of(input.size());
  std::vector<Item> items;
  items.reserve(input.size());
  for (std::size_t k = 0; k < by_id.size(); ++k) {
    const auto pos = by_id[k].second;
    if (k > 0 && by_id[k].first == by_id[k - 1].first) {
      item_of[pos] = item_of[by_id[k - 1].second];
      continue;
    }
    item_of[pos] = items.size();
    items.push_back({input[pos], pruningBox(*input[pos]), input_map[pos]});
  }

  DisjointSets sets(items.size());
  std::size_t pos = 0;
  for (const auto* m : maps) {
    for (const auto& object : m->objects) {
      const std::size_t first = item_of[pos];
      for (std::size_t k = 0; k < object.ellipsoids.size(); ++k) sets.unite(first, item_of[pos++]);
    }
  }

  // All-pairs count: pairs from different maps and different nodes =
  // all pairs - pairs within a map - pairs within a node + pairs within both.
  {
    auto pairsWithin = [](const auto& counts) {
      std::uint64_t p = 0;
      for (const auto& [key, c] : counts) p += c * (c - 1) / 2;
      return p;
    };
    std::map<std::size_t, std::uint64_t> per_map;
    std::map<std::uint32_t, std::uint64_t> per_node;
    std::map<std::pair<std::size_t, std::uint32_t>, std::uint64_t> per_both;
    for (const auto& it : items) {
      ++per_map[it.map];
      ++per_node[it.ellipsoid->node()];
      ++per_both[{it.map, it.ellipsoid->node()}];
    }
    const auto n = static_cast<std::uint64_t>(items.size());
    result.stats.pairs_all = n * (n - (n > 0 ? 1 : 0)) / 2 - pairsWithin(per_map) - pairsWithin(per_node) + pairsWithin(per_both);
  }

  // Sort-and-sweep over the ellipsoids' pruning boxes along x (ellipsoid boxes prune better
  // than object boxes: merged objects grow long). Pairs from one input map are already decided by
  // that map; pairs of one node are never joined directly.
  std::vector<std::size_t> sweep(items.size());
  std::iota(sweep.begin(), sweep.end(), 0);
  std::sort(sweep.begin(), sweep.end(), [&](std::size_t a, std::size_t b) { return items[a].box.min.x() < items[b].box.min.x(); });
  std::vector<std::size_t> active;
  for (const auto cur : sweep) {
    const Item& ec = items[cur];
    std::erase_if(active, [&](std::size_t a) { return items[a].box.max.x() < ec.box.min.x(); });
    for (const auto other : active) {
      const Item& eo = items[other];
      if (eo.map == ec.map || eo.ellipsoid->node() == ec.ellipsoid->node() || !eo.box.overlaps(ec.box)) continue;
      if (sets.find(cur) == sets.find(other)) continue;
      ++result.stats.pairs_tested;
      if (intersects(*eo.ellipsoid, *ec.ellipsoid)) sets.unite(cur, other);
    }
    active.push_back(cur);
  }
  result.stats.pairs_pruned = result.stats.pairs_all - std::min(result.stats.pairs_all, result.stats.pairs_tested);

  std::vector<Ellipsoid> merged;
  std::vector<std::size_t> object_of;
  merged.reserve(items.size());
  object_of.reserve(items.size());
  for (std::size_t i = 0; i < items.size(); ++i) {
    merged.push_back(*items[i].ellipsoid);
    object_of.push_back(sets.find(i));
  }
  result.map = mapFromGroups(merged, object_of);
  return result;
}

MergeResult merge(const Map& working, const Map& child) {
  const std::array<const Map*, 2> maps{&working, &child};
  return mergeMaps(maps);
}

MergeResult mergeAll(std::span<const Map> maps) {
  std::vector<const Map*> pointers;
  pointers.reserve(maps.size());
  for (const auto& m : maps) pointers.push_back(&m);
  return mergeMaps(pointers);
}

Map mergeSpecification(std::span<const Ellipsoid> ellipsoids, std::uint64_t min_points) {
  std::vector<Ellipsoid> unique(ellipsoids.begin(), ellipsoids.end());
  std::sort(unique.begin(), unique.end(), [](const Ellipsoid& a, const Ellipsoid& b) { return a.id < b.id; });
  unique.erase(std::unique(unique.begin(), unique.end(), [](const Ellipsoid& a, const Ellipsoid& b) { return a.id == b.id; }),
               unique.end());
  DisjointSets sets(unique.size());
  for (std::size_t i = 0; i < unique.size(); ++i) {
    for (std::size_t j = i + 1; j < unique.size(); ++j) {
      if (unique[i].node() != unique[j].node() && intersects(unique[i], unique[j])) sets.unite(i, j);
    }
  }
  std::vector<std::size_t> object_of(unique.size());
  for (std::size_t i = 0; i < unique.size(); ++i) object_of[i] = sets.find(i);
  Map components = mapFromGroups(unique, object_of);
  return min_points == 0 ? components : withoutFragments(components, min_points);
}

}  // namespace fogmap
