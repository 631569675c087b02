#include "common/clustering.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <deque>
#include <memory>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

#include "common/map.hpp"

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

// Squared distance exactly as FLANN's L2_Simple computes it (float, x then y then z), so that the
// strict "closer than eps" decision matches PCL's radius search bit for bit.
inline float squaredDistance(const float* a, const float* b) {
  float r = 0.0F;
  float d = a[0] - b[0];
  r += d * d;
  d = a[1] - b[1];
  r += d * d;
  d = a[2] - b[2];
  r += d * d;
  return r;
}

pcl::PointCloud<pcl::PointXYZ>::Ptr toPcl(std::span<const Point> points) {
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) (*cloud)[i] = pcl::PointXYZ(points[i].x, points[i].y, points[i].z);
  return cloud;
}

int bitsFor(std::uint64_t span) { return span == 0 ? 1 : static_cast<int>(std::bit_width(span)); }

// LSD radix sort of (key, payload) pairs by key, 11 bits a pass, only over the bits in use.
void radixSort(std::vector<std::uint64_t>& keys, std::vector<std::uint32_t>& payload, int key_bits) {
  constexpr int kDigitBits = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigitBits;
  std::vector<std::uint64_t> keys_tmp(keys.size());
  std::vector<std::uint32_t> payload_tmp(payload.size());
  std::vector<std::uint32_t> offsets(kBuckets);
  for (int shift = 0; shift < key_bits; shift += kDigitBits) {
    std::fill(offsets.begin(), offsets.end(), 0U);
    for (const auto k : keys) ++offsets[(k >> shift) & (kBuckets - 1)];
    std::uint32_t sum = 0;
    for (auto& o : offsets) {
      const auto c = o;
      o = sum;
      sum += c;
    }
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const auto pos = offsets[(keys[i] >> shift) & (kBuckets - 1)]++;
      keys_tmp[pos] = keys[i];
      payload_tmp[pos] = payload[i];
    }
    keys.swap(keys_tmp);
    payload.swap(payload_tmp);
  }
}

}  // namespace

Clustering euclideanClusters(std::span<const Point> points, const ClusteringParams& params) {
  const std::size_t n = points.size();
  if (n == 0) return {};
  // Cell edge slightly under eps/sqrt(3): any two points of one cell are closer than eps, so a
  // cell is connected for free. Points closer than eps are then at most two cells apart per axis.
  const double cell = params.eps_m / std::sqrt(3.0) * (1.0 - 1e-5);
  const auto eps2 = static_cast<float>(params.eps_m * params.eps_m);

  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const auto& p : points) {
    const Eigen::Vector3d q(p.x, p.y, p.z);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  // Two cells of margin so that neighbour offsets never leave the coordinate range.
  const Eigen::Vector3d origin = lo - Eigen::Vector3d::Constant(2.0 * cell);
  std::array<std::uint64_t, 3> span{};
  for (int a = 0; a < 3; ++a) span[a] = static_cast<std::uint64_t>(std::floor((hi[a] - origin[a]) / cell)) + 3;
  const int bz = bitsFor(span[2]);
  const int by = bitsFor(span[1]);
  const int bx = bitsFor(span[0]);
  if (bx + by + bz > 63) {
    // A scene wider than ~10^5 km at this eps: no packed key fits, use the reference.
    return pclEuclideanClusters(points, params, false);
  }
  auto cellKey = [&](const Point& p) {
    const auto ix = static_cast<std::uint64_t>((p.x - origin[0]) / cell);
    const auto iy = static_cast<std::uint64_t>((p.y - origin[1]) / cell);
    const auto iz = static_cast<std::uint64_t>((p.z - origin[2]) / cell);
    return (ix << (by + bz)) | (iy << bz) | iz;
  };

  std::vector<std::uint64_t> keys(n);
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) {
    keys[i] = cellKey(points[i]);
    order[i] = static_cast<std::uint32_t>(i);
  }
  radixSort(keys, order, bx + by + bz);

  // Points in cell order, packed xyz for the closest-pair checks; cells as runs.
  std::vector<float> xyz(3 * n);
  std::vector<std::uint32_t> cell_begin;
  std::vector<std::uint64_t> cell_key;
  cell_begin.reserve(n / 2 + 1);
  cell_key.reserve(n / 2 + 1);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& p = points[order[i]];
    xyz[3 * i] = p.x;
    xyz[3 * i + 1] = p.y;
    xyz[3 * i + 2] = p.z;
    if (i == 0 || keys[i] != keys[i - 1]) {
      cell_begin.push_back(static_cast<std::uint32_t>(i));
      cell_key.push_back(keys[i]);
    }
  }
  const std::size_t cells = cell_key.size();
  cell_begin.push_back(static_cast<std::uint32_t>(n));

  // Tight box of each cell's points: most neighbouring cells are too far apart to hold a close
  // pair, and inside a pair check only points near the other cell's box can match.
  std::vector<std::array<float, 6>> cell_box(cells);
  for (std::size_t c = 0; c < cells; ++c) {
    auto& b = cell_box[c];
    const float* p = &xyz[3 * cell_begin[c]];
    b = {p[0], p[1], p[2], p[0], p[1], p[2]};
    for (auto i = cell_begin[c] + 1; i < cell_begin[c + 1]; ++i) {
      for (int a = 0; a < 3; ++a) {
        b[a] = std::min(b[a], xyz[3 * i + a]);
        b[3 + a] = std::max(b[3 + a], xyz[3 * i + a]);
      }
    }
  }
  // A box gap this large rules a pair out; the slack keeps rounding from ruling out a true pair.
  const float gap_limit = eps2 * 1.0001F;
  auto boxGap2 = [](const float* lo_hi, const float* p) {
    float g = 0.0F;
    for (int a = 0; a < 3; ++a) {
      const float d = std::max(std::max(lo_hi[a] - p[a], p[a] - lo_hi[3 + a]), 0.0F);
      g += d * d;
    }
    return g;
  };
  auto boxesGap2 = [](const std::array<float, 6>& x, const std::array<float, 6>& y) {
    float g = 0.0F;
    for (int a = 0; a < 3; ++a) {
      const float d = std::max(std::max(x[a] - y[3 + a], y[a] - x[3 + a]), 0.0F);
      g += d * d;
    }
    return g;
  };

  auto closeCells = [&](std::size_t a, std::size_t b) {
    for (auto i = cell_begin[a]; i < cell_begin[a + 1]; ++i) {
      if (boxGap2(cell_box[b].data(), &xyz[3 * i]) > gap_limit) continue;
      for (auto j = cell_begin[b]; j < cell_begin[b + 1]; ++j) {
        if (squaredDistance(&xyz[3 * i], &xyz[3 * j]) < eps2) return true;
      }
    }
    return false;
  };

  // Neighbour cells lie at most two cells away per axis; only the forward half is visited (each
  // unordered pair once). In key order the cells of columns (x + dx, y - 2 .. y + 2) form one
  // contiguous run, whose bounds are the cell's key plus constants, so for each dx the runs of
  // consecutive cells start at non-decreasing positions: one cursor per dx walks the sorted keys
  // once (a merge join of the list with itself), with no hashing; a z test drops the cells of
  // the middle columns that are more than two cells above or below.
  const std::int64_t x_unit = std::int64_t{1} << (by + bz);
  const std::int64_t y_unit = std::int64_t{1} << bz;
  const std::uint64_t z_mask = (std::uint64_t{1} << bz) - 1;
  std::array<std::size_t, 3> cursor{};
  DisjointSets sets(cells);
  for (std::size_t c = 0; c < cells; ++c) {
    const auto key = static_cast<std::int64_t>(cell_key[c]);
    const auto cz = static_cast<std::int64_t>(cell_key[c] & z_mask);
    const std::array<float, 6> box = cell_box[c];
    std::size_t root = sets.find(c);
    for (std::int64_t dx = 0; dx <= 2; ++dx) {
      // dx = 0: the cells above in the same column, then columns y + 1 and y + 2.
      const std::int64_t lo = dx == 0 ? key + 1 : key + dx * x_unit - 2 * y_unit - 2;
      const std::int64_t hi = key + dx * x_unit + 2 * y_unit + 2;
      auto o = cursor[static_cast<std::size_t>(dx)];
      while (o < cells && static_cast<std::int64_t>(cell_key[o]) < lo) ++o;
      cursor[static_cast<std::size_t>(dx)] = o;
      for (; o < cells && static_cast<std::int64_t>(cell_key[o]) <= hi; ++o) {
        const auto oz = static_cast<std::int64_t>(cell_key[o] & z_mask);
        if (oz < cz - 2 || oz > cz + 2) continue;
        if (boxesGap2(box, cell_box[o]) > gap_limit) continue;
        if (sets.find(o) == root) continue;
        if (closeCells(c, o)) {
          sets.unite(c, o);
          root = sets.find(c);
        }
      }
    }
  }

  // Component sizes, then canonical labels in the order of each cluster's first point.
  std::vector<std::uint32_t> root_of(cells);
  std::vector<std::uint64_t> component_size(cells, 0);
  for (std::size_t c = 0; c < cells; ++c) {
    root_of[c] = static_cast<std::uint32_t>(sets.find(c));
    component_size[root_of[c]] += cell_begin[c + 1] - cell_begin[c];
  }
  std::vector<std::uint32_t> cell_of_point(n);
  for (std::size_t c = 0; c < cells; ++c) {
    for (auto i = cell_begin[c]; i < cell_begin[c + 1]; ++i) cell_of_point[order[i]] = static_cast<std::uint32_t>(c);
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
