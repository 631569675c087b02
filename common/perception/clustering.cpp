#include "common/perception/clustering.hpp"
#include "common/perception/radix_sort.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <deque>
#include <memory>
#include <optional>
#include <thread>
#include <utility>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
// The template's implementation, instantiated here: libpcl_segmentation is not linked.
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/impl/extract_clusters.hpp>

#include "common/geometry/map.hpp"

namespace fogmap {

Clustering canonicalize(std::span<const std::int32_t> labels) {
  Clustering out;
  out.labels.assign(labels.size(), -1);
  std::int32_t max_label = -1;
  for (const auto l : labels) max_label = std::max(max_label, l);
  std::vector<std::int32_t> renamed(static_cast<std::size_t>(max_label + 1), -1);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const auto l = labels[i];
    if (l < 0) continue;
    auto& r = renamed[static_cast<std::size_t>(l)];
    if (r < 0) r = out.cluster_count++;
    out.labels[i] = r;
  }
  return out;
}

namespace {

pcl::PointCloud<pcl::PointXYZ>::Ptr toPcl(std::span<const Point> points) {
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) (*cloud)[i] = pcl::PointXYZ(points[i].x, points[i].y, points[i].z);
  return cloud;
}

// Squared distance exactly as FLANN's L2_Simple computes it (float, x then y then z), so that the
// strict "closer than eps" decision matches PCL's radius search bit for bit.
inline float squaredDistance(float ax, float ay, float az, float bx, float by, float bz) {
  float r = 0.0F;
  float d = ax - bx;
  r += d * d;
  d = ay - by;
  r += d * d;
  d = az - bz;
  r += d * d;
  return r;
}

// eps^2 as PCL's EuclideanClusterExtraction compares squared distances with it: the tolerance is
// cast to float, then squared and rounded to float for FLANN's radius search. (Rounding eps^2
// from double instead gives another float for about half of all eps, 0.35 among them.)
float pclSquaredTolerance(double eps_m) {
  const auto eps = static_cast<float>(eps_m);
  return eps * eps;  // the exact product rounded once, as float(double(eps) * eps) in PCL
}

int bitsFor(std::uint64_t span) { return span == 0 ? 1 : static_cast<int>(std::bit_width(span)); }

// Four lanes of a 128-bit register (GCC/Clang vector extension; plain SSE2 or NEON code).
using Floats4 = float __attribute__((vector_size(16)));
using Ints4 = std::int32_t __attribute__((vector_size(16)));
constexpr std::size_t kLanes = 4;
constexpr std::size_t kChunk = 2 * kLanes;  // cells filtered at once
constexpr std::size_t kMinCellsPerThread = 4096;  // below this a thread costs more than it saves

template <typename V, typename T>
V loadLanes(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

Floats4 gapLanes(Floats4 lo, Floats4 hi, Floats4 other_lo, Floats4 other_hi) {
  const Floats4 a = lo - other_hi;
  const Floats4 b = other_lo - hi;
  const Floats4 g = a > b ? a : b;
  return g > Floats4{} ? g : Floats4{};
}

// The points sorted into grid cells, cells into (x, y) columns, in key order (x, then y, then z).
struct SortedGrid {
  int z_bits = 0;
  int y_bits = 0;
  std::vector<std::uint64_t> words;  // per sorted point: cell key << index_bits | input index
  std::uint64_t index_mask = 0;
  std::vector<float> x, y, z;        // per sorted point, padded by a lane group
  std::vector<std::uint32_t> cell_begin;  // cells as runs of sorted points, plus the end
  std::vector<std::int32_t> cell_z;       // z index per cell, padded by a chunk
  std::array<std::vector<float>, 6> box;  // tight box per cell (lo xyz, hi xyz), padded by a chunk
  std::vector<std::uint32_t> column_begin;  // columns as runs of cells, plus the end
  std::vector<std::uint64_t> column_key;    // (x, y) per column, plus a sentinel
  std::size_t cells() const { return cell_z.size() - kChunk; }
  std::size_t columns() const { return column_key.size() - 1; }
};

// Most cells along one axis. Cell indices are computed in double with a relative error of a few
// 2^-53, which stays under 1e-6 of a cell below 2^30 cells: well inside the relative 1e-5 by
// which a cell is smaller than eps/sqrt(3), so a cell's points are still closer than eps. Indices (and z
// differences) also fit an int32 then, and no conversion from double goes out of range.
constexpr double kMaxCellsPerAxis = 1073741824.0;  // 2^30

// Whether the grid decides "closer than eps" exactly as FLANN does. It connects the points of a
// cell without a distance test, which agrees with FLANN only while FLANN's float eps^2 is a
// normal float (at 0 not even duplicates are closer than eps; a denormal one is rounded by more
// than the cell's margin) and while every cell index is accurate (at most kMaxCellsPerAxis
// cells from lo to hi on each axis). Checked in double, before any index becomes an integer.
bool gridIsExact(float eps2, double cell, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  if (!std::isnormal(eps2) || !(cell > 0.0)) return false;
  for (int a = 0; a < 3; ++a) {
    if (!((hi[a] - lo[a]) / cell < kMaxCellsPerAxis)) return false;  // also false for NaN
  }
  return true;
}

// Cell edge slightly under eps/sqrt(3): any two points of one cell are closer than eps (also
// after rounding eps^2 and their squared distance to float), so a cell is connected for free.
// Points closer than eps are then at most two cells apart per axis. Returns nothing when the
// grid would not be exact (gridIsExact) or the scene is too wide for one 64-bit word per point.
std::optional<SortedGrid> sortIntoGrid(std::span<const Point> points, double eps, float eps2) {
  const std::size_t n = points.size();
  const double cell = eps / std::sqrt(3.0) * (1.0 - 1e-5);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : points) {
    const Eigen::Vector3d q(p.x, p.y, p.z);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  if (!gridIsExact(eps2, cell, lo, hi)) return std::nullopt;
  // Two cells of margin so that neighbour offsets never leave the coordinate range.
  const Eigen::Vector3d origin = lo - Eigen::Vector3d::Constant(2.0 * cell);
  std::array<int, 3> bits{};
  for (int a = 0; a < 3; ++a) bits[a] = bitsFor(static_cast<std::uint64_t>(std::floor((hi[a] - origin[a]) / cell)) + 3);
  const int key_bits = bits[0] + bits[1] + bits[2];
  const int index_bits = bitsFor(n);
  if (key_bits + index_bits > 64) return std::nullopt;

  SortedGrid g;
  g.z_bits = bits[2];
  g.y_bits = bits[1];
  g.index_mask = (std::uint64_t{1} << index_bits) - 1;
  const double inv_cell = 1.0 / cell;
  g.words.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& p = points[i];
    const auto ix = static_cast<std::uint64_t>(static_cast<std::int64_t>((p.x - origin[0]) * inv_cell));
    const auto iy = static_cast<std::uint64_t>(static_cast<std::int64_t>((p.y - origin[1]) * inv_cell));
    const auto iz = static_cast<std::uint64_t>(static_cast<std::int64_t>((p.z - origin[2]) * inv_cell));
    g.words[i] = (((ix << (bits[1] + bits[2])) | (iy << bits[2]) | iz) << index_bits) | i;
  }
  radixSort(g.words, index_bits, key_bits);

  g.x.assign(n + kLanes, 0.0F);
  g.y.assign(n + kLanes, 0.0F);
  g.z.assign(n + kLanes, 0.0F);
  std::vector<std::uint64_t> cell_key;
  cell_key.reserve(n / 2 + 1);
  g.cell_begin.reserve(n / 2 + 1);
  constexpr std::size_t kPrefetch = 16;
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kPrefetch < n) __builtin_prefetch(&points[g.words[i + kPrefetch] & g.index_mask]);
    const auto& p = points[g.words[i] & g.index_mask];
    g.x[i] = p.x;
    g.y[i] = p.y;
    g.z[i] = p.z;
    const auto key = g.words[i] >> index_bits;
    if (i == 0 || key != cell_key.back()) {
      g.cell_begin.push_back(static_cast<std::uint32_t>(i));
      cell_key.push_back(key);
    }
  }
  const std::size_t cells = cell_key.size();
  g.cell_begin.push_back(static_cast<std::uint32_t>(n));

  const std::uint64_t z_mask = (std::uint64_t{1} << g.z_bits) - 1;
  g.cell_z.assign(cells + kChunk, 0);
  for (auto& b : g.box) b.assign(cells + kChunk, 0.0F);
  for (std::size_t c = 0; c < cells; ++c) {
    g.cell_z[c] = static_cast<std::int32_t>(cell_key[c] & z_mask);
    auto i = g.cell_begin[c];
    std::array<float, 6> b{g.x[i], g.y[i], g.z[i], g.x[i], g.y[i], g.z[i]};
    for (++i; i < g.cell_begin[c + 1]; ++i) {
      b[0] = std::min(b[0], g.x[i]);
      b[1] = std::min(b[1], g.y[i]);
      b[2] = std::min(b[2], g.z[i]);
      b[3] = std::max(b[3], g.x[i]);
      b[4] = std::max(b[4], g.y[i]);
      b[5] = std::max(b[5], g.z[i]);
    }
    for (int a = 0; a < 6; ++a) g.box[a][c] = b[a];
  }
  for (std::size_t c = 0; c < cells; ++c) {
    const auto column = cell_key[c] >> g.z_bits;
    if (c == 0 || column != g.column_key.back()) {
      g.column_begin.push_back(static_cast<std::uint32_t>(c));
      g.column_key.push_back(column);
    }
  }
  g.column_begin.push_back(static_cast<std::uint32_t>(cells));
  g.column_key.push_back(std::numeric_limits<std::uint64_t>::max());
  return g;
}

// Union-find over cells: every pair of cells holding two points closer than eps is joined.
// Columns are visited in key order and only forward pairs are looked at (each unordered pair
// once). The later cells that can hold a neighbour of a column's cells form three contiguous
// runs in key order: the rest of the column and columns (x, y+1), (x, y+2); columns
// (x+1, y-2 .. y+2); columns (x+2, y-2 .. y+2). Their bounds are the column key plus constants,
// so five cursors walk the column list once (a merge join of the list with itself, no hashing).
// Each run is filtered a chunk of cells at a time, branch-free: z index within two, box gap under
// eps, and not already known to be joined (`known`: a snapshot of the sets' roots, one per cell,
// padded by a chunk); the survivors get the union-find test and an early-exit closest-pair check.
// `eps2` is pclSquaredTolerance. Visits columns [first, last); every union made is also
// appended to `joined` when given.
void joinCloseCells(const SortedGrid& g, std::span<const std::int32_t> known, float eps2, std::size_t first,
                    std::size_t last, DisjointSets& sets, std::vector<std::pair<std::uint32_t, std::uint32_t>>* joined) {
  const float gap_limit = eps2 * 1.0001F;  // slack so that rounding never drops a true pair
  // Plain references, not a structured binding: the lambdas below capture them (clang < 16).
  const std::vector<float>& lx = g.box[0];
  const std::vector<float>& ly = g.box[1];
  const std::vector<float>& lz = g.box[2];
  const std::vector<float>& hx = g.box[3];
  const std::vector<float>& hy = g.box[4];
  const std::vector<float>& hz = g.box[5];

  auto closeCells = [&](std::size_t a, std::size_t b) {
    for (auto i = g.cell_begin[a]; i < g.cell_begin[a + 1]; ++i) {
      const float gx = std::max(std::max(lx[b] - g.x[i], g.x[i] - hx[b]), 0.0F);
      const float gy = std::max(std::max(ly[b] - g.y[i], g.y[i] - hy[b]), 0.0F);
      const float gz = std::max(std::max(lz[b] - g.z[i], g.z[i] - hz[b]), 0.0F);
      if (gx * gx + gy * gy + gz * gz > gap_limit) continue;
      for (auto j = g.cell_begin[b]; j < g.cell_begin[b + 1]; ++j) {
        if (squaredDistance(g.x[i], g.y[i], g.z[i], g.x[j], g.y[j], g.z[j]) < eps2) return true;
      }
    }
    return false;
  };

  // Bit k set: cell base + k (k < count) is within two z cells of c, its box within eps, and it
  // is not known to be joined with c.
  auto candidates = [&](std::size_t c, std::size_t base, std::size_t count) {
    const Floats4 cx0 = Floats4{} + lx[c], cy0 = Floats4{} + ly[c], cz0 = Floats4{} + lz[c];
    const Floats4 cx1 = Floats4{} + hx[c], cy1 = Floats4{} + hy[c], cz1 = Floats4{} + hz[c];
    unsigned mask = 0;
    for (std::size_t h = 0; h < kChunk; h += kLanes) {
      const std::size_t o = base + h;
      const Floats4 gx = gapLanes(cx0, cx1, loadLanes<Floats4>(&lx[o]), loadLanes<Floats4>(&hx[o]));
      const Floats4 gy = gapLanes(cy0, cy1, loadLanes<Floats4>(&ly[o]), loadLanes<Floats4>(&hy[o]));
      const Floats4 gz = gapLanes(cz0, cz1, loadLanes<Floats4>(&lz[o]), loadLanes<Floats4>(&hz[o]));
      const Ints4 dz = loadLanes<Ints4>(&g.cell_z[o]) - g.cell_z[c];
      const Ints4 pass = (gx * gx + gy * gy + gz * gz <= gap_limit) & (dz >= -2) & (dz <= 2) &
                         (loadLanes<Ints4>(&known[o]) != known[c]);
      const Ints4 bit = pass & Ints4{1, 2, 4, 8};
      mask |= static_cast<unsigned>(bit[0] | bit[1] | bit[2] | bit[3]) << h;
    }
    return count < kChunk ? mask & ((1U << count) - 1) : mask;
  };

  const std::uint64_t x_unit = std::uint64_t{1} << g.y_bits;
  // First column at or after (x, y+3), (x+1, y-2), (x+1, y+3), (x+2, y-2), (x+2, y+3).
  std::array<std::size_t, 5> cursor{};
  cursor.fill(first);
  auto firstCellFrom = [&](std::size_t& k, std::uint64_t column) {
    while (g.column_key[k] < column) ++k;
    return g.column_begin[k];
  };
  for (std::size_t col = first; col < last; ++col) {
    const auto key = g.column_key[col];
    const std::array<std::uint32_t, 3> run_end{firstCellFrom(cursor[0], key + 3),
                                               firstCellFrom(cursor[2], key + x_unit + 3),
                                               firstCellFrom(cursor[4], key + 2 * x_unit + 3)};
    const std::array<std::uint32_t, 2> run_begin{firstCellFrom(cursor[1], key + x_unit - 2),
                                                 firstCellFrom(cursor[3], key + 2 * x_unit - 2)};
    for (auto c = g.column_begin[col]; c < g.column_begin[col + 1]; ++c) {
      std::size_t root = sets.find(c);
      for (std::size_t r = 0; r < 3; ++r) {
        const std::size_t begin = r == 0 ? c + 1 : run_begin[r - 1];
        for (std::size_t base = begin; base < run_end[r]; base += kChunk) {
          for (auto mask = candidates(c, base, run_end[r] - base); mask != 0; mask &= mask - 1) {
            const std::size_t o = base + static_cast<std::size_t>(std::countr_zero(mask));
            if (sets.find(o) == root || !closeCells(c, o)) continue;
            sets.unite(c, o);
            if (joined != nullptr) joined->emplace_back(c, static_cast<std::uint32_t>(o));
            root = sets.find(c);
          }
        }
      }
    }
  }
}

// The columns split into `threads` ranges of about equal cell counts, one per thread. The first
// range joins into `sets` directly; the others into sets of their own, whose unions are replayed
// into `sets` afterwards (pairs across a range boundary belong to the range of their first cell).
void joinCloseCellsParallel(const SortedGrid& g, std::span<const std::int32_t> known, float eps2, std::size_t threads,
                            DisjointSets& sets) {
  const std::size_t columns = g.columns();
  threads = std::clamp<std::size_t>(threads, 1, std::max<std::size_t>(1, g.cells() / kMinCellsPerThread));
  std::vector<std::size_t> bounds{0};
  for (std::size_t t = 1; t < threads; ++t) {
    const auto cell = static_cast<std::uint32_t>(g.cells() * t / threads);
    const auto it = std::lower_bound(g.column_begin.begin(), g.column_begin.begin() + static_cast<std::ptrdiff_t>(columns), cell);
    bounds.push_back(std::max(bounds.back(), static_cast<std::size_t>(it - g.column_begin.begin())));
  }
  bounds.push_back(columns);
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> joined(threads);
  std::vector<DisjointSets> own(threads - 1, sets);  // copied before any thread writes to `sets`
  std::vector<std::thread> workers;
  for (std::size_t t = 1; t < threads; ++t) {
    workers.emplace_back([&, t] { joinCloseCells(g, known, eps2, bounds[t], bounds[t + 1], own[t - 1], &joined[t]); });
  }
  joinCloseCells(g, known, eps2, bounds[0], bounds[1], sets, nullptr);
  for (auto& w : workers) w.join();
  for (const auto& edges : joined) {
    for (const auto& [a, b] : edges) sets.unite(a, b);
  }
}

// Non-finite points are noise and connect to nothing (PCL's KdTree asserts on them): when there
// are any, `cluster` runs on the finite points alone and their labels are put back in place.
template <typename ClusterFn>
std::optional<Clustering> withoutNonFinite(std::span<const Point> points, ClusterFn&& cluster) {
  if (std::all_of(points.begin(), points.end(), isFinitePoint)) return std::nullopt;
  Cloud finite;
  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isFinitePoint(points[i])) continue;
    finite.push_back(points[i]);
    index.push_back(i);
  }
  const Clustering inner = cluster(std::span<const Point>(finite));
  Clustering out;
  out.cluster_count = inner.cluster_count;  // relative order kept: the labels stay canonical
  out.labels.assign(points.size(), -1);
  for (std::size_t k = 0; k < index.size(); ++k) out.labels[index[k]] = inner.labels[k];
  return out;
}

}  // namespace

Clustering euclideanClusters(std::span<const Point> points, const ClusteringParams& params) {
  const std::size_t n = points.size();
  if (n == 0) return {};
  if (auto r = withoutNonFinite(points, [&](std::span<const Point> finite) { return euclideanClusters(finite, params); })) {
    return std::move(*r);
  }
  const float eps2 = pclSquaredTolerance(params.eps_m);
  const auto grid = sortIntoGrid(points, params.eps_m, eps2);
  // A far outlier, a scene wider than 2^30 cells or an eps whose square underflows in float: the
  // grid cannot decide exactly, the reference can (such input is rare and worth no fast path).
  if (!grid) return pclEuclideanClusters(points, params, false);
  const std::size_t cells = grid->cells();
  std::vector<std::uint32_t> cell_of_point(n);
  for (std::size_t c = 0; c < cells; ++c) {
    for (auto i = grid->cell_begin[c]; i < grid->cell_begin[c + 1]; ++i) {
      cell_of_point[grid->words[i] & grid->index_mask] = static_cast<std::uint32_t>(c);
    }
  }
  // Scans arrive in acquisition order, where consecutive points are mostly neighbours: joining
  // those first is exact (they are closer than eps) and lets the search skip most pairs of cells
  // already joined.
  DisjointSets sets(cells);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    if (cell_of_point[i] == cell_of_point[i + 1]) continue;
    const Point& a = points[i];
    const Point& b = points[i + 1];
    if (squaredDistance(a.x, a.y, a.z, b.x, b.y, b.z) < eps2) sets.unite(cell_of_point[i], cell_of_point[i + 1]);
  }
  std::vector<std::int32_t> known(cells + kChunk, -1);
  for (std::size_t c = 0; c < cells; ++c) known[c] = static_cast<std::int32_t>(sets.find(c));
  joinCloseCellsParallel(*grid, known, eps2, params.threads, sets);

  // Component sizes, then canonical labels in the order of each cluster's first point.
  std::vector<std::uint32_t> root_of(cells);
  std::vector<std::uint64_t> component_size(cells, 0);
  for (std::size_t c = 0; c < cells; ++c) {
    root_of[c] = static_cast<std::uint32_t>(sets.find(c));
    component_size[root_of[c]] += grid->cell_begin[c + 1] - grid->cell_begin[c];
  }
  std::vector<std::int32_t> label_of_root(cells, -2);  // -2: not yet decided
  Clustering out;
  out.labels.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto root = root_of[cell_of_point[i]];
    auto& label = label_of_root[root];
    if (label == -2) {
      const auto size = component_size[root];
      label = (size >= params.min_points && size <= params.max_points) ? out.cluster_count++ : -1;
    }
    out.labels[i] = label;
  }
  return out;
}

Clustering pclEuclideanClusters(std::span<const Point> points, const ClusteringParams& params, bool sorted_search) {
  if (auto r = withoutNonFinite(points, [&](std::span<const Point> finite) {
        return pclEuclideanClusters(finite, params, sorted_search);
      })) {
    return std::move(*r);
  }
  const auto cloud = toPcl(points);
  std::vector<std::int32_t> labels(points.size(), -1);
  if (points.empty()) return {};
  auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>(sorted_search);
  tree->setInputCloud(cloud);
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> extraction;
  extraction.setClusterTolerance(params.eps_m);
  extraction.setMinClusterSize(static_cast<pcl::uindex_t>(params.min_points));
  extraction.setMaxClusterSize(static_cast<pcl::uindex_t>(std::min<std::size_t>(params.max_points, std::numeric_limits<pcl::uindex_t>::max())));
  extraction.setSearchMethod(tree);
  extraction.setInputCloud(cloud);
  std::vector<pcl::PointIndices> clusters;
  extraction.extract(clusters);
  for (std::size_t c = 0; c < clusters.size(); ++c) {
    for (const auto idx : clusters[c].indices) labels[static_cast<std::size_t>(idx)] = static_cast<std::int32_t>(c);
  }
  return canonicalize(labels);
}

Clustering clusterPoints(std::span<const Point> points, const ClusteringParams& params, ClusteringMethod method) {
  switch (method) {
    case ClusteringMethod::kFogmap: return euclideanClusters(points, params);
    case ClusteringMethod::kPcl: return pclEuclideanClusters(points, params, true);
    case ClusteringMethod::kPclUnsorted: return pclEuclideanClusters(points, params, false);
  }
  return euclideanClusters(points, params);
}

Clustering dbscan(std::span<const Point> points, const DbscanParams& params) {
  const std::size_t n = points.size();
  if (n == 0) return {};
  if (auto r = withoutNonFinite(points, [&](std::span<const Point> finite) { return dbscan(finite, params); })) {
    return std::move(*r);
  }
  const auto cloud = toPcl(points);
  pcl::search::KdTree<pcl::PointXYZ> tree(false);
  tree.setInputCloud(cloud);

  std::vector<std::vector<pcl::index_t>> neighbours(n);
  std::vector<float> distances;
  std::vector<char> core(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    tree.radiusSearch((*cloud)[i], params.eps_m, neighbours[i], distances);
    core[i] = neighbours[i].size() >= params.min_neighbours ? 1 : 0;
  }
  constexpr std::int32_t kUnassigned = -2;
  std::vector<std::int32_t> labels(n, kUnassigned);
  std::int32_t next = 0;
  std::deque<std::size_t> queue;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (!core[seed] || labels[seed] != kUnassigned) continue;
    const std::int32_t id = next++;
    labels[seed] = id;
    queue.assign(1, seed);
    while (!queue.empty()) {
      const auto p = queue.front();
      queue.pop_front();
      for (const auto q_idx : neighbours[p]) {
        const auto q = static_cast<std::size_t>(q_idx);
        if (labels[q] != kUnassigned) continue;
        labels[q] = id;
        if (core[q]) queue.push_back(q);  // only core points expand the cluster
      }
    }
  }
  std::vector<std::size_t> sizes(static_cast<std::size_t>(next), 0);
  for (auto& l : labels) {
    if (l == kUnassigned) l = -1;
    if (l >= 0) ++sizes[static_cast<std::size_t>(l)];
  }
  for (auto& l : labels) {
    if (l >= 0 && sizes[static_cast<std::size_t>(l)] < params.min_cluster_points) l = -1;
  }
  return canonicalize(labels);
}

std::vector<ClusterSummary> summarizeClusters(std::span<const Point> points, const Clustering& clustering) {
  std::vector<ClusterSummary> summaries(static_cast<std::size_t>(clustering.cluster_count));
  for (std::size_t i = 0; i < points.size() && i < clustering.labels.size(); ++i) {
    const auto l = clustering.labels[i];
    if (l >= 0) summaries[static_cast<std::size_t>(l)].add(points[i]);
  }
  return summaries;
}

}  // namespace fogmap
