#include "common/map.hpp"

#include <algorithm>
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

// Working set of a MERGE: deduplicated ellipsoids with their boxes and source map.
struct Item {
  const Ellipsoid* ellipsoid;
  Box box;
};

struct Group {
  std::vector<std::size_t> members;  // indices into the item list
  Box box;
  bool from_child = false;
};

}  // namespace

MergeResult merge(const Map& working, const Map& child) {
  MergeResult result;
  std::vector<Item> items;
  items.reserve(working.ellipsoidCount() + child.ellipsoidCount());
  std::vector<Group> groups;
  groups.reserve(working.objects.size() + child.objects.size());

  std::vector<std::pair<EllipsoidId, std::size_t>> working_ids;  // sorted (id, item index)
  working_ids.reserve(working.ellipsoidCount());
  for (const auto& object : working.objects) {
    Group g;
    for (const auto& e : object.ellipsoids) {
      working_ids.emplace_back(e.id, items.size());
      g.members.push_back(items.size());
      items.push_back({&e, delimitingBox(e)});
      g.box.extend(items.back().box);
    }
    groups.push_back(std::move(g));
  }
  std::sort(working_ids.begin(), working_ids.end());
  const std::size_t working_items = items.size();

  // A child ellipsoid whose id the working map already holds is the same ellipsoid (ids are
  // globally unique): it stays one item, and the child's grouping still joins through it.
  for (const auto& object : child.objects) {
    Group g;
    g.from_child = true;
    for (const auto& e : object.ellipsoids) {
      const auto it = std::lower_bound(working_ids.begin(), working_ids.end(), std::make_pair(e.id, std::size_t{0}));
      if (it != working_ids.end() && it->first == e.id) {
        g.members.push_back(it->second);
        continue;
      }
      g.members.push_back(items.size());
      items.push_back({&e, delimitingBox(e)});
      g.box.extend(items.back().box);
    }
    groups.push_back(std::move(g));
  }

  DisjointSets sets(items.size());
  for (const auto& g : groups) {
    for (std::size_t k = 1; k < g.members.size(); ++k) sets.unite(g.members[0], g.members[k]);
  }

  // All-pairs count: every cross-node pair between working and (new) child ellipsoids.
  {
    std::vector<std::uint32_t> nodes;
    for (std::size_t i = working_items; i < items.size(); ++i) nodes.push_back(items[i].ellipsoid->node());
    std::sort(nodes.begin(), nodes.end());
    for (std::size_t i = 0; i < working_items; ++i) {
      const auto node = items[i].ellipsoid->node();
      const auto same = std::upper_bound(nodes.begin(), nodes.end(), node) - std::lower_bound(nodes.begin(), nodes.end(), node);
      result.stats.pairs_all += nodes.size() - static_cast<std::size_t>(same);
    }
  }

  // Sort-and-sweep over object boxes along x; only working x child object pairs matter.
  std::vector<std::size_t> sweep;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (!groups[g].box.empty()) sweep.push_back(g);  // child objects made only of duplicates have no new items
  }
  std::sort(sweep.begin(), sweep.end(), [&](std::size_t a, std::size_t b) { return groups[a].box.min.x() < groups[b].box.min.x(); });
  std::vector<std::size_t> active;
  for (const auto g : sweep) {
    const Group& cur = groups[g];
    std::erase_if(active, [&](std::size_t a) { return groups[a].box.max.x() < cur.box.min.x(); });
    for (const auto a : active) {
      const Group& other = groups[a];
      if (other.from_child == cur.from_child || !other.box.overlaps(cur.box)) continue;
      const Group& old_group = other.from_child ? cur : other;
      const Group& new_group = other.from_child ? other : cur;
      for (const auto i : old_group.members) {
        for (const auto j : new_group.members) {
          if (j < working_items) continue;  // a duplicate: its edges to the working map are known
          const Item& ei = items[i];
          const Item& ej = items[j];
          if (ei.ellipsoid->node() == ej.ellipsoid->node() || !ei.box.overlaps(ej.box)) continue;
          if (sets.find(i) == sets.find(j)) continue;
          ++result.stats.pairs_tested;
          if (intersects(*ei.ellipsoid, *ej.ellipsoid)) sets.unite(i, j);
        }
      }
    }
    active.push_back(g);
  }
  result.stats.pairs_pruned = result.stats.pairs_all - result.stats.pairs_tested;

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

MergeResult mergeAll(std::span<const Map> maps) {
  MergeResult total;
  for (const auto& m : maps) {
    auto step = merge(total.map, m);
    total.map = std::move(step.map);
    total.stats.pairs_all += step.stats.pairs_all;
    total.stats.pairs_tested += step.stats.pairs_tested;
    total.stats.pairs_pruned += step.stats.pairs_pruned;
  }
  return total;
}

Map mergeSpecification(std::span<const Ellipsoid> ellipsoids) {
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
  return mapFromGroups(unique, object_of);
}

}  // namespace fogmap
