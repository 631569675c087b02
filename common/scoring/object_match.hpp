#pragma once
// Object-level agreement of a clustering with the truth (simulated scenes give every point its
// true object): which true objects were found whole, split into several objects, merged with
// another, or missed. Point-level agreement is common/scoring/rand_index.hpp.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/base/status.hpp"

namespace fogmap {

struct ObjectMatchParams {
  std::size_t min_points = 10;  // true objects with fewer points are not counted (not visible enough)
  double found = 0.5;           // a true object is found when one cluster holds at least this share of it
  double share = 0.1;           // a cluster "holds" a true object when it has at least this share of it
};

struct ObjectMatch {
  std::size_t objects_true = 0;   // true objects with at least min_points points
  std::size_t found_whole = 0;    // found, in one cluster, sharing it with no other true object
  std::size_t split = 0;          // found or not, at least two clusters hold it
  std::size_t merged = 0;         // found, and its best cluster also holds another true object
  std::size_t missed = 0;         // no cluster holds the `found` share of it
};

// What became of one counted true object (ObjectMatch's definitions, for that object alone).
struct ObjectOutcome {
  std::int64_t true_object = 0;
  std::size_t points = 0;    // its points (at least min_points)
  bool found_whole = false;  // neither split, nor merged, nor missed
  bool split = false;
  bool merged = false;
  bool missed = false;
};

// `truth`: the true object of every point (negative: not an object, e.g. ground); `clusters`: the
// cluster of every point (negative: noise). A true object can be both split and merged; found whole
// is neither split, nor merged, nor missed. Errors when the lengths differ.
Expected<ObjectMatch> matchObjects(std::span<const std::int64_t> truth, std::span<const std::int64_t> clusters,
                                   const ObjectMatchParams& params = {});

// The same judgement per true object: one outcome for every true object with at least min_points
// points, in increasing true_object order; matchObjects is countOutcomes of it. Errors when the
// lengths differ.
Expected<std::vector<ObjectOutcome>> matchEachObject(std::span<const std::int64_t> truth,
                                                     std::span<const std::int64_t> clusters,
                                                     const ObjectMatchParams& params = {});

// The counts of `outcomes`: objects_true is their number, the others how many are so.
ObjectMatch countOutcomes(std::span<const ObjectOutcome> outcomes);

}  // namespace fogmap
