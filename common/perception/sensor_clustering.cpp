#include "common/perception/sensor_clustering.hpp"
#include "common/base/angles.hpp"
#include "common/perception/radix_sort.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <string>
#include <utility>

#include "common/base/text.hpp"
#include "common/geometry/map.hpp"

namespace fogmap {

BeamTable beamTableOf(const LidarModel& model) {
  return {model.elevations_deg, 360.0 / model.azimuth_steps};
}

namespace {

// The range image is sorted as 64-bit words: cell (ring x bins + bin) above, point index below.
constexpr int kIndexBits = 32;
constexpr std::uint64_t kIndexMask = 0xFFFFFFFFU;
constexpr double kMaxBins = 16777216.0;        // 2^24 azimuth bins per ring
constexpr double kMaxCells = 4294967295.0;     // rings x bins below 2^32
// The range image is sorted by counting, with a table of where each cell starts, where it has at
// most kCellsPerPoint cells per point plus kCellTableSlack (a whole frame of a real sensor: a
// VLP-16 has 28,800 cells, an HDL-64E 133,000); otherwise, a frame of few points among many cells
// (a VLP-16's objects alone), by a radix sort, and the windows are found by cursors. Measured on
// a VLP-16: the table costs about 0.6 ns per cell, and saves about 12 ns per point.
constexpr std::uint64_t kCellsPerPoint = 8;
constexpr std::uint64_t kCellTableSlack = 1024;
// Cells of the sine of the elevation, [-1, 1], in the ring lookup: far finer than any real ring
// spacing (1/3 degree is 0.005 in sine at 25 degrees), so a lookup is one comparison.
constexpr int kSineCells = 4096;
// The fast atan2 is within 4.1e-8 rad of the true angle (its polynomial's error, measured on a
// dense grid of [0, 1]); it decides a bin alone only where the bin's edges are further than this.
constexpr double kFastAtanError = 1e-6;
// Next to an edge, the side of the edge decides, from the edge's direction (errors below 1e-13
// rad: the formula's roundings, the table's recurrence), where the point is further from the edge
// than this angle. Simulated rays lie on the edges, up to the rounding of float coordinates
// (1e-8 to 1e-7 rad): only a point within this of the edge needs std::atan2.
constexpr double kEdgeTolerance = 1e-12;
// The table of edge directions: for at most this many bins (every real sensor), from std::sin
// and std::cos every kEdgeRestart edges, by rotation by one step in between.
constexpr int kMaxEdgeTable = 65536;
constexpr int kEdgeRestart = 64;

double azimuthBinCount(double step_deg) { return std::ceil(360.0 / step_deg - 1e-9); }

// The cell of sine s: floor((s + 1) kSineCells / 2) within [0, kSineCells). Truncation is the
// floor here: below 0 it gives 0, as the clamp would.
int sineCell(double s) {
  const int c = static_cast<int>((s + 1.0) * (kSineCells / 2));
  return std::clamp(c, 0, kSineCells - 1);
}

// atan(r) for r in [0, 1] as r P(r^2): a least-squares fit at Chebyshev nodes, error 4.1e-8.
double atanUnit(double r) {
  constexpr double c[] = {0.9999994368431484,  -0.33330106677688937, 0.1994850898576519,  -0.13915802260683555,
                          0.09656256470427399, -0.05606317672859198, 0.021946611032241853, -0.004073309464366758};
  const double u = r * r;
  double p = c[7];
  for (int k = 6; k >= 0; --k) p = p * u + c[k];
  return r * p;
}

// The points that have a beam, sorted by (ring, azimuth bin): their words (cell << 32 | input
// index), their components under rule (a), where each ring's run starts. Ranges and coordinates
// are looked up by input index, only for pairs on two components, which are few.
struct RangeImage {
  std::vector<std::uint64_t> words;
  std::unique_ptr<std::int32_t[]> component;
  std::unique_ptr<double[]> range;  // in image order: the pairs' first test reads neighbours in it
  std::vector<std::uint32_t> ring_begin;  // per ring, plus the end
  // Where each cell's points start, per cell plus the end, where the image has few enough cells
  // per point (kCellsPerPoint, kCellTableSlack); empty otherwise (the windows are then found by
  // cursors).
  std::vector<std::uint32_t> cell_begin;
  int bins = 1;
  int binAt(std::size_t k, int ring) const {
    return static_cast<int>((words[k] >> kIndexBits) - static_cast<std::uint64_t>(ring) * static_cast<std::uint64_t>(bins));
  }
  std::size_t indexAt(std::size_t k) const { return static_cast<std::size_t>(words[k] & kIndexMask); }
};

// Rule (b) between the runs of ring r and ring r + 1, each sorted by bin. The window [b - w, b + w]
// of the upper ring moves forward with the lower point's bin b, so its ends are cursors that only
// advance; near the seam the window wraps around into [b - w + bins, bins) or [0, b + w - bins],
// with cursors of their own (with 2w + 1 < bins the pieces never overlap; otherwise every pair of
// the two rings is in the window).
void linkAdjacentRings(const RangeImage& image, int r, std::span<const Point> points, int window, double eps,
                       double gap_link, DisjointSets& sets) {
  const std::size_t a_begin = image.ring_begin[static_cast<std::size_t>(r)];
  const std::size_t a_end = image.ring_begin[static_cast<std::size_t>(r) + 1];
  const std::size_t b_begin = a_end;
  const std::size_t b_end = image.ring_begin[static_cast<std::size_t>(r) + 2];
  const int bins = image.bins;
  const std::int32_t* component = image.component.get();
  // The last two components joined: along a ring the same two surfaces meet again and again.
  std::int32_t joined_i = -1;
  std::int32_t joined_j = -1;
  // i and j on two components under rule (a), with ranges closer than eps.
  auto tryLink = [&](std::size_t i, std::size_t j) {
    const auto ci = component[i];
    const auto cj = component[j];
    if (ci == joined_i && cj == joined_j) return;
    const double reach = gap_link * std::min(image.range[i], image.range[j]);
    if (!(reach > eps)) return;
    const std::size_t pi = image.indexAt(i);
    const std::size_t pj = image.indexAt(j);
    const double dx = static_cast<double>(points[pi].x) - static_cast<double>(points[pj].x);
    const double dy = static_cast<double>(points[pi].y) - static_cast<double>(points[pj].y);
    const double dz = static_cast<double>(points[pi].z) - static_cast<double>(points[pj].z);
    if (dx * dx + dy * dy + dz * dz < reach * reach) {
      sets.unite(static_cast<std::size_t>(ci), static_cast<std::size_t>(cj));
      joined_i = ci;
      joined_j = cj;
    }
  };
  // Points [first, last) of the upper ring against point i. Most are on i's component under rule
  // (a) (one surface), or further in range than eps (the ground's rings): neither needs more, and
  // both are tested in one branch, all but never taken.
  const double* range = image.range.get();
  auto scan = [&](std::size_t i, std::size_t first, std::size_t last) {
    const auto ci = component[i];
    const double ri = range[i];
    for (auto j = first; j < last; ++j) {
      if (component[j] != ci && std::abs(range[j] - ri) < eps) [[unlikely]] tryLink(i, j);
    }
  };
  if (2 * static_cast<std::int64_t>(window) + 1 >= bins) {
    for (auto i = a_begin; i < a_end; ++i) scan(i, b_begin, b_end);
    return;
  }
  if (!image.cell_begin.empty()) {
    // The window's ends from the table: two loads, independent from one point to the next.
    const std::uint32_t* upper = image.cell_begin.data() + static_cast<std::size_t>(r + 1) * static_cast<std::size_t>(bins);
    const auto at = [&](int bin) { return static_cast<std::size_t>(upper[bin]); };
    for (auto i = a_begin; i < a_end; ++i) {
      const int b = image.binAt(i, r);
      scan(i, at(std::max(b - window, 0)), at(std::min(b + window + 1, bins)));
      if (b - window < 0) [[unlikely]] scan(i, at(b - window + bins), b_end);
      if (b + window >= bins) [[unlikely]] scan(i, b_begin, at(b + window - bins + 1));
    }
    return;
  }
  auto advance = [&](std::size_t& k, int min_bin) {
    while (k < b_end && image.binAt(k, r + 1) < min_bin) ++k;
  };
  std::size_t lo = b_begin, hi = b_begin, wrap_lo = b_begin, wrap_hi = b_begin;
  for (auto i = a_begin; i < a_end; ++i) {
    const int b = image.binAt(i, r);
    advance(lo, b - window);
    advance(hi, b + window + 1);
    scan(i, lo, hi);
    if (b - window < 0) {
      advance(wrap_lo, b - window + bins);
      scan(i, wrap_lo, b_end);
    }
    if (b + window >= bins) {
      advance(wrap_hi, b + window - bins + 1);
      scan(i, b_begin, wrap_hi);
    }
  }
}

}  // namespace

Status validateSensorClusteringParams(const SensorClusteringParams& params) {
  const double eps = params.clustering.eps_m;
  if (!std::isfinite(eps) || !(eps > 0.0)) {
    return invalidArgument("clustering.eps_m must be positive and finite, got " + readableNumber(eps));
  }
  const auto& elevations = params.links.beams.elevations_deg;
  if (elevations.size() < 2) {
    return invalidArgument("beams.elevations_deg needs at least 2 rings, got " + std::to_string(elevations.size()));
  }
  for (std::size_t k = 0; k < elevations.size(); ++k) {
    const double e = elevations[k];
    if (!std::isfinite(e) || e < -90.0 || e > 90.0) {
      return invalidArgument("beams.elevations_deg[" + std::to_string(k) + "] must be finite and within [-90, 90] degrees, got " +
                             readableNumber(e));
    }
  }
  // Distinct in radians, as the rings are told apart (two degree values one ulp apart may not be).
  std::vector<double> sorted_rad(elevations.size());
  std::transform(elevations.begin(), elevations.end(), sorted_rad.begin(), [](double e) { return e * kDegToRad; });
  std::sort(sorted_rad.begin(), sorted_rad.end());
  if (const auto dup = std::adjacent_find(sorted_rad.begin(), sorted_rad.end()); dup != sorted_rad.end()) {
    return invalidArgument("beams.elevations_deg holds the elevation " + readableNumber(*dup / kDegToRad) +
                           " degrees twice: every ring needs its own");
  }
  const double step = params.links.beams.azimuth_step_deg;
  if (!std::isfinite(step) || !(step > 0.0)) {
    return invalidArgument("beams.azimuth_step_deg must be positive and finite, got " + readableNumber(step));
  }
  const double bins = azimuthBinCount(step);
  if (bins > kMaxBins || bins * static_cast<double>(elevations.size()) > kMaxCells) {
    return invalidArgument("beams.azimuth_step_deg " + readableNumber(step) + " is too small: " + readableNumber(bins) + " azimuth bins x " +
                           std::to_string(elevations.size()) + " rings exceed the range image's 2^24 bins per ring or 2^32 cells");
  }
  if (!std::isfinite(params.links.ring_gap_slack) || params.links.ring_gap_slack < 1.0) {
    return invalidArgument("ring_gap_slack must be at least 1 and finite, got " + readableNumber(params.links.ring_gap_slack));
  }
  if (params.links.azimuth_window < 0) {
    return invalidArgument("azimuth_window must be at least 0, got " + std::to_string(params.links.azimuth_window));
  }
  const Eigen::Matrix3d rotation = params.links.sensor_pose.linear();
  if (!params.links.sensor_pose.matrix().allFinite() ||
      !((rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm() < 1e-6) || !(rotation.determinant() > 0.0)) {
    return invalidArgument("sensor_pose must be finite and rigid (a rotation and a translation)");
  }
  return {};
}

Expected<BeamGeometry> BeamGeometry::make(const SensorClusteringParams& params) {
  if (Status valid = validateSensorClusteringParams(params); !valid) return valid.error();
  BeamGeometry g;
  for (const double e : params.links.beams.elevations_deg) g.elevations_rad_.push_back(e * kDegToRad);
  std::sort(g.elevations_rad_.begin(), g.elevations_rad_.end());
  for (std::size_t k = 0; k + 1 < g.elevations_rad_.size(); ++k) {
    g.sin_midpoints_.push_back(std::sin(0.5 * (g.elevations_rad_[k] + g.elevations_rad_[k + 1])));
  }
  // Cell c holds the sines from -1 + 2c / kSineCells on; rings whose upper midpoint lies below
  // that (with a margin far above the rounding of sineCell) are below every sine of the cell.
  g.ring_below_.resize(kSineCells);
  std::size_t below = 0;
  for (int c = 0; c < kSineCells; ++c) {
    const double lowest = -1.0 + 2.0 * c / kSineCells - 1e-12;
    while (below < g.sin_midpoints_.size() && g.sin_midpoints_[below] < lowest) ++below;
    g.ring_below_[static_cast<std::size_t>(c)] = static_cast<std::int32_t>(below);
  }
  // The top ring's sentinel: no sine is above it.
  g.sin_midpoints_.push_back(std::numeric_limits<double>::infinity());
  g.to_sensor_ = params.links.sensor_pose.inverse();
  g.step_rad_ = params.links.beams.azimuth_step_deg * kDegToRad;
  g.bins_per_rad_ = 1.0 / g.step_rad_;
  g.closing_bin_ = 2.0 * std::numbers::pi * g.bins_per_rad_;
  g.fast_margin_ = kFastAtanError * g.bins_per_rad_ + 1e-6;
  g.bins_ = static_cast<int>(azimuthBinCount(params.links.beams.azimuth_step_deg));
  if (g.bins_ <= kMaxEdgeTable) {
    const auto edges = static_cast<std::size_t>(g.bins_);
    g.edge_cos_.resize(edges);
    g.edge_sin_.resize(edges);
    const double step_cos = std::cos(g.step_rad_);
    const double step_sin = std::sin(g.step_rad_);
    for (std::size_t k = 0; k < edges; ++k) {
      if (k % kEdgeRestart == 0) {
        const double edge = -std::numbers::pi + static_cast<double>(k) * g.step_rad_;
        g.edge_cos_[k] = std::cos(edge);
        g.edge_sin_[k] = std::sin(edge);
      } else {
        g.edge_cos_[k] = g.edge_cos_[k - 1] * step_cos - g.edge_sin_[k - 1] * step_sin;
        g.edge_sin_[k] = g.edge_sin_[k - 1] * step_cos + g.edge_cos_[k - 1] * step_sin;
      }
    }
  }
  return g;
}

int BeamGeometry::exactAzimuthBin(double x, double y) const {
  // atan2 gives (-pi, pi]: its pi is the direction of -pi, where the bins start.
  const double azimuth = std::atan2(y, x);
  const double from_back = azimuth == std::numbers::pi ? 0.0 : azimuth + std::numbers::pi;
  const int bin = static_cast<int>(std::max(0.0, std::floor(from_back / step_rad_)));
  return bin >= bins_ ? bin - bins_ : bin;
}

inline int BeamGeometry::ringOfSine(double sine) const {
  int ring = ring_below_[static_cast<std::size_t>(sineCell(sine))];
  ring += sin_midpoints_[static_cast<std::size_t>(ring)] < sine ? 1 : 0;
  while (sin_midpoints_[static_cast<std::size_t>(ring)] < sine) ++ring;  // rings closer than a cell
  return ring;
}

inline double BeamGeometry::fastBinCoordinate(double x, double y) const {
  // Each fold computed, then selected: no branch (a block of points is one vector loop).
  const double ax = std::abs(x);
  const double ay = std::abs(y);
  const double first = atanUnit(std::min(ax, ay) / std::max(ax, ay));
  const double second_octant = 0.5 * std::numbers::pi - first;
  const double quadrant = ay > ax ? second_octant : first;
  const double left = std::numbers::pi - quadrant;
  const double half = x < 0.0 ? left : quadrant;
  const double below = -half;
  const double angle = y < 0.0 ? below : half;
  return (angle + std::numbers::pi) * bins_per_rad_;
}

// The fast coordinate's bin wherever no bin edge is within fast_margin_ of it (nor the closing
// angle pi): the true angle is in the same bin, and that is the exact formula's bin. Next to edge
// k (the table's margin is under a quarter bin), the sign of the cross product of the edge's
// direction and the point's: k beyond the edge, k - 1 before it, as the formula's floor, whose
// roundings move its edge by under 1e-14 rad. The others take the formula. Simulated rays lie on
// the edges, on either side at random: both answers are computed and one is selected, with no
// branch on the side or on the nearness to an edge.
inline int BeamGeometry::azimuthBin(double fast_coordinate, double x, double y) const {
  const double t = fast_coordinate;
  if (!(t >= 0.0 && t < closing_bin_ - fast_margin_)) [[unlikely]] {  // true for NaN
    return exactAzimuthBin(x, y);
  }
  const int below = static_cast<int>(t);            // floor: t >= 0
  const int nearest = static_cast<int>(t + 0.5);    // the nearest edge
  const bool near_edge = std::abs(t - nearest) <= fast_margin_;
  if (edge_cos_.empty()) [[unlikely]] {
    return near_edge ? exactAzimuthBin(x, y) : below;
  }
  // nearest = bins_ only where rounding puts 2 pi past the last bin (then the formula decides).
  const auto edge = static_cast<std::size_t>(std::min(nearest, bins_ - 1));
  const double side = y * edge_cos_[edge] - x * edge_sin_[edge];
  const int beside = nearest - (side < 0.0 ? 1 : 0);
  const bool undecided = (nearest >= bins_) | (beside < 0) | !(std::abs(side) > kEdgeTolerance * (std::abs(x) + std::abs(y)));
  if (near_edge & undecided) [[unlikely]] {
    return exactAzimuthBin(x, y);
  }
  return near_edge ? beside : below;
}

BeamIndex BeamGeometry::index(const Point& point) const {
  BeamIndex out;
  if (!isFinitePoint(point)) return out;
  const SensorPoint s = toSensor(point);
  out.range_m = s.range;
  if (!(s.range > 0.0)) return out;
  out.ring = ringOfSine(s.z / s.range);
  out.azimuth_bin = azimuthBin(fastBinCoordinate(s.x, s.y), s.x, s.y);
  return out;
}

SensorClusterer::SensorClusterer(SensorClusteringParams params, BeamGeometry geometry)
    : params_(std::move(params)), geometry_(std::move(geometry)) {
  // The range image holds each point a ring link could reach past eps from (see the header): a
  // point of ring r is kept where its range times the wider link of ring r's two gaps (slack x gap)
  // is above eps; elsewhere every reach through it is at most eps (the products are monotonic in
  // both factors, roundings included).
  const int rings = geometry_.rings();
  gap_link_.resize(static_cast<std::size_t>(rings) - 1);
  for (int r = 0; r + 1 < rings; ++r) {
    gap_link_[static_cast<std::size_t>(r)] = params_.links.ring_gap_slack * (geometry_.elevationRad(r + 1) - geometry_.elevationRad(r));
  }
  ring_link_.resize(static_cast<std::size_t>(rings));
  for (std::size_t r = 0; r < ring_link_.size(); ++r) {
    ring_link_[r] = std::max(r > 0 ? gap_link_[r - 1] : 0.0, r + 1 < ring_link_.size() ? gap_link_[r] : 0.0);
  }
  // Nearer than this no ring's link reaches past eps: such points are passed over on their
  // squared range, before the square root, with a margin of 1e-6 far above its roundings.
  const double widest_link = *std::max_element(gap_link_.begin(), gap_link_.end());
  const double near_range = params_.clustering.eps_m / widest_link * (1.0 - 1e-6);
  near_squared_ = near_range * near_range;
}

Expected<SensorClusterer> SensorClusterer::create(const SensorClusteringParams& params) {
  auto geometry = BeamGeometry::make(params);
  if (!geometry) return geometry.error();
  return SensorClusterer(params, std::move(*geometry));
}

Expected<Clustering> sensorAwareClusters(std::span<const Point> points, const SensorClusteringParams& params) {
  const auto clusterer = SensorClusterer::create(params);
  if (!clusterer) return clusterer.error();
  return clusterer->cluster(points);
}

Expected<Clustering> SensorClusterer::cluster(std::span<const Point> points) const {
  const SensorClusteringParams& params = params_;
  const BeamGeometry* geometry = &geometry_;
  const std::size_t n = points.size();
  if (n == 0) return Clustering{};
  if (n > std::numeric_limits<std::uint32_t>::max()) {
    return resourceExhausted("sensor-aware clustering takes at most 2^32 - 1 points, got " + std::to_string(n));
  }

  // Rule (a): the exact Euclidean components, every finite point in one (min 1, no max).
  ClusteringParams exact = params.clustering;
  exact.min_points = 1;
  exact.max_points = std::numeric_limits<std::size_t>::max();
  const Clustering linked = euclideanClusters(points, exact);
  const auto components = static_cast<std::size_t>(linked.cluster_count);

  // The range image: each point kept (see the constructor) as a word (cell << 32 | index),
  // sorted by cell.
  const int rings = geometry->rings();
  const int bins = geometry->azimuthBins();
  const double eps = params.clustering.eps_m;
  const std::vector<double>& gap_link = gap_link_;
  const std::vector<double>& ring_link = ring_link_;
  const double near_squared = near_squared_;
  const auto range_of = std::make_unique_for_overwrite<double[]>(n);
  std::vector<std::uint64_t> words;
  words.reserve(n);
  const auto cells = static_cast<std::uint64_t>(rings) * static_cast<std::uint64_t>(bins);
  // index() in passes over blocks of points, each pass one loop over arrays (a vector loop where
  // the compiler can make one): the transform; the squared range, the range and the sine of the
  // elevation; the tests and the ring, keeping the points a ring link could reach past eps from;
  // the fast azimuth of the kept ones; their bins and words.
  constexpr std::size_t kBlock = 256;
  std::array<Eigen::Vector3d, kBlock> local;
  std::array<double, kBlock> squared;
  std::array<double, kBlock> range;
  std::array<double, kBlock> sine;
  std::array<double, kBlock> kept_x;
  std::array<double, kBlock> kept_y;
  std::array<double, kBlock> kept_range;
  std::array<double, kBlock> fast_coordinate;
  std::array<std::uint32_t, kBlock> kept_index;
  std::array<int, kBlock> kept_ring;
  for (std::size_t first = 0; first < n; first += kBlock) {
    const std::size_t count = std::min(kBlock, n - first);
    for (std::size_t k = 0; k < count; ++k) local[k] = geometry->toSensorFrame(points[first + k]);
    for (std::size_t k = 0; k < count; ++k) squared[k] = local[k].squaredNorm();
    for (std::size_t k = 0; k < count; ++k) {
      range[k] = std::sqrt(squared[k]);
      sine[k] = local[k].z() / range[k];
    }
    std::size_t kept = 0;
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t i = first + k;
      // Non-finite points (label -1 under rule a) and near ones (NaN compares false) are passed.
      if (linked.labels[i] < 0 || !(squared[k] > near_squared)) continue;
      const int ring = geometry->ringOfSine(sine[k]);
      if (!(range[k] * ring_link[static_cast<std::size_t>(ring)] > eps)) continue;
      kept_x[kept] = local[k].x();
      kept_y[kept] = local[k].y();
      kept_range[kept] = range[k];
      kept_ring[kept] = ring;
      kept_index[kept] = static_cast<std::uint32_t>(i);
      ++kept;
    }
    for (std::size_t k = 0; k < kept; ++k) fast_coordinate[k] = geometry->fastBinCoordinate(kept_x[k], kept_y[k]);
    for (std::size_t k = 0; k < kept; ++k) {
      const int ring = kept_ring[k];
      const int bin = geometry->azimuthBin(fast_coordinate[k], kept_x[k], kept_y[k]);
      range_of[kept_index[k]] = kept_range[k];
      const auto cell = static_cast<std::uint64_t>(ring) * static_cast<std::uint64_t>(bins) + static_cast<std::uint64_t>(bin);
      words.push_back((cell << kIndexBits) | kept_index[k]);
    }
  }
  RangeImage image;
  image.bins = bins;
  image.ring_begin.assign(1, 0);
  if (cells <= kCellsPerPoint * static_cast<std::uint64_t>(words.size()) + kCellTableSlack) {
    // A counting sort: each cell's end, then the words placed from the last down (stable: the
    // points of a cell stay in input order, as the radix sort leaves them); the ends have then
    // become the starts.
    std::vector<std::uint32_t> tally(static_cast<std::size_t>(cells) + 1, 0);
    for (const auto w : words) ++tally[static_cast<std::size_t>(w >> kIndexBits)];
    std::uint32_t end = 0;
    for (auto& c : tally) c = end += c;
    std::vector<std::uint64_t> sorted(words.size());
    for (auto k = words.size(); k-- > 0;) sorted[--tally[static_cast<std::size_t>(words[k] >> kIndexBits)]] = words[k];
    words.swap(sorted);
    for (int r = 1; r <= rings; ++r) image.ring_begin.push_back(tally[static_cast<std::size_t>(r) * static_cast<std::size_t>(bins)]);
    image.cell_begin = std::move(tally);
  } else {
    radixSort(words, kIndexBits, std::bit_width(cells - 1));
    // Each ring's start: the first word whose cell lies in a later ring.
    const auto bins64 = static_cast<std::uint64_t>(bins);
    std::size_t k = 0;
    for (int r = 1; r <= rings; ++r) {
      while (k < words.size() && (words[k] >> kIndexBits) / bins64 < static_cast<std::uint64_t>(r)) ++k;
      image.ring_begin.push_back(static_cast<std::uint32_t>(k));
    }
  }

  image.component = std::make_unique_for_overwrite<std::int32_t[]>(words.size());
  image.range = std::make_unique_for_overwrite<double[]>(words.size());
  for (std::size_t k = 0; k < words.size(); ++k) {
    const std::size_t i = words[k] & kIndexMask;
    image.component[k] = linked.labels[i];
    image.range[k] = range_of[i];
  }
  image.words = std::move(words);

  // Rule (b) over every pair of adjacent rings, on the components of rule (a).
  DisjointSets sets(components);
  for (int r = 0; r + 1 < rings; ++r) {
    linkAdjacentRings(image, r, points, params.links.azimuth_window, eps, gap_link[static_cast<std::size_t>(r)], sets);
  }

  // Sizes of the joined components, then canonical labels in the order of each cluster's first point.
  std::vector<std::uint32_t> component_size(components, 0);
  for (const auto l : linked.labels) {
    if (l >= 0) ++component_size[static_cast<std::size_t>(l)];
  }
  std::vector<std::uint32_t> root_of(components);
  std::vector<std::uint32_t> joined_size(components, 0);
  for (std::size_t c = 0; c < components; ++c) {
    root_of[c] = static_cast<std::uint32_t>(sets.find(c));
    joined_size[root_of[c]] += component_size[c];
  }
  std::vector<std::int32_t> label_of_root(components, -2);  // -2: not yet decided
  Clustering out;
  out.labels.assign(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const auto l = linked.labels[i];
    if (l < 0) continue;
    const auto root = root_of[static_cast<std::size_t>(l)];
    auto& label = label_of_root[root];
    if (label == -2) {
      const auto size = joined_size[root];
      label = (size >= params.clustering.min_points && size <= params.clustering.max_points) ? out.cluster_count++ : -1;
    }
    out.labels[i] = label;
  }
  return out;
}

}  // namespace fogmap
