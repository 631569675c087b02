#pragma once
// Maps and MERGE (MAD-C Algorithm 2, DESIGN.md 2.2). A map is a set of objects; an object is a
// set of ellipsoids. MERGE unions two maps and joins objects that own intersecting ellipsoids
// from different source nodes; the result equals the connected components of the cross-node
// overlap graph of all ellipsoids, so MERGE is commutative, associative and idempotent.
#include <cstdint>
#include <span>
#include <vector>

#include "common/geometry/ellipsoid.hpp"

namespace fogmap {

// Disjoint sets with union by rank and path compression.
class DisjointSets {
 public:
  explicit DisjointSets(std::size_t n = 0);
  void reset(std::size_t n);
  std::size_t find(std::size_t x);
  // Returns true when x and y were in different sets.
  bool unite(std::size_t x, std::size_t y);
  std::size_t size() const { return parent_.size(); }

 private:
  std::vector<std::uint32_t> parent_;
  std::vector<std::uint8_t> rank_;
};

struct MapObject {
  std::vector<Ellipsoid> ellipsoids;  // sorted by id
  Box box;                            // union of the ellipsoids' delimiting boxes
  bool operator==(const MapObject&) const = default;
  // The object's points over all its sensors: the sum of its ellipsoids' point counts.
  std::uint64_t pointCount() const;
};

// Canonical form: ellipsoids of an object sorted by id, objects sorted by their first id, no
// duplicate ids. Equal maps in canonical form are equal member by member.
struct Map {
  std::vector<MapObject> objects;
  bool operator==(const Map&) const = default;
  std::size_t ellipsoidCount() const;
};

// A local map: every ellipsoid is its own object (one node's clusters are already separated).
Map localMap(std::vector<Ellipsoid> ellipsoids);
// Groups ellipsoids into objects by `object_of[i]` and returns the canonical map.
Map mapFromGroups(std::span<const Ellipsoid> ellipsoids, std::span<const std::size_t> object_of);

struct MergeStats {
  std::uint64_t pairs_all = 0;     // cross-node ellipsoid pairs an all-pairs MERGE would test
  std::uint64_t pairs_tested = 0;  // exact intersection tests run after box pruning
  std::uint64_t pairs_pruned = 0;  // pairs_all - pairs_tested
};

struct MergeResult {
  Map map;
  MergeStats stats;
};

// MERGE(working, child): box pruning with a sort-and-sweep over the ellipsoids' delimiting boxes
// (grown past the exact test's touching tolerance, so pruning never drops a pair it accepts),
// then the exact test. Duplicate ellipsoid ids (the same ellipsoid seen twice) count once.
MergeResult merge(const Map& working, const Map& child);
// MERGE of any number of maps in one pass (equal to folding merge() over them).
MergeResult mergeAll(std::span<const Map> maps);
MergeResult mergeMaps(std::span<const Map* const> maps);

// Fragments (docs/design.md, "Fragments"): an edge ships every local cluster, also
// those below min_points, and min_points applies to a global object's points over all its sensors.
// The published map is the merged map without the objects below min_points: a pure function of
// the merged map, so MERGE stays commutative, associative and idempotent and the published map
// does not depend on the order of arrivals. Intermediate aggregators keep every fragment.
Map withoutFragments(const Map& merged, std::uint64_t min_points);

// The specification, for tests and small inputs: connected components of the graph of all
// (deduplicated) ellipsoids with an edge between intersecting ellipsoids of different nodes,
// found by testing all pairs; with min_points, without the components of fewer points over all
// their ellipsoids (the published map: lone fragments are not objects).
Map mergeSpecification(std::span<const Ellipsoid> ellipsoids, std::uint64_t min_points = 0);

}  // namespace fogmap
