#include "common/geometry/compact_ellipsoid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "common/base/little_endian.hpp"

namespace fogmap {

namespace {

constexpr std::int32_t kCentreLimitCm = 32767;
constexpr std::uint32_t kU16Max = 65535;
constexpr int kComponentBits = 15;
constexpr std::uint64_t kComponentMask = (std::uint64_t{1} << kComponentBits) - 1;
constexpr int kIndexShift = 3 * kComponentBits;      // bits 45..46
constexpr int kReservedBit = kIndexShift + 2;        // bit 47
constexpr double kComponentZero = 16383.0;           // k for a component of 0
// One step of a kept component: (1 / sqrt(2)) / 16383.
constexpr double kComponentStep = std::numbers::sqrt2 / 2.0 / kComponentZero;
// Rounding leaves an honest record's kept three far below 1 (at most 3/4 + 1e-4); this only keeps
// the decoder from refusing a value that is 1 up to rounding.
constexpr double kQuaternionNormTolerance = 1e-9;
constexpr int kOrientationOffset = 12;

// The record's fields as integers, before they are laid out in bytes.
struct CompactFields {
  std::array<std::int16_t, 3> centre_cm{};
  std::array<std::uint16_t, 3> semi_axes_mm{};
  std::uint64_t orientation = 0;  // the 48-bit word
  std::uint16_t point_count = 0;
  std::uint16_t index = 0;
};

// The rotation of the shape's eigenvectors as the quaternion of largest |w| among the four that
// give the same shape (R, and R with two columns negated: R Rx(pi), R Ry(pi), R Rz(pi)), w >= 0.
Eigen::Quaterniond canonicalRotation(Eigen::Matrix3d r) {
  if (r.determinant() < 0.0) r.col(0) = -r.col(0);
  Eigen::Quaterniond q(r);
  q.normalize();
  // q (x) i has w = -x, q (x) j has w = -y, q (x) k has w = -z.
  const std::array<double, 4> magnitude = {std::abs(q.w()), std::abs(q.x()), std::abs(q.y()), std::abs(q.z())};
  const auto largest = std::max_element(magnitude.begin(), magnitude.end()) - magnitude.begin();
  if (largest == 1) q = q * Eigen::Quaterniond(0.0, 1.0, 0.0, 0.0);
  if (largest == 2) q = q * Eigen::Quaterniond(0.0, 0.0, 1.0, 0.0);
  if (largest == 3) q = q * Eigen::Quaterniond(0.0, 0.0, 0.0, 1.0);
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q;
}

// Smallest three: drop the component of largest magnitude (made positive), keep the others in
// (w, x, y, z) order as 15-bit codes.
std::uint64_t packOrientation(Eigen::Quaterniond q) {
  std::array<double, 4> c = {q.w(), q.x(), q.y(), q.z()};
  std::size_t dropped = 0;
  for (std::size_t i = 1; i < 4; ++i) {
    if (std::abs(c[i]) > std::abs(c[dropped])) dropped = i;
  }
  if (c[dropped] < 0.0) {
    for (double& v : c) v = -v;
  }
  std::uint64_t word = std::uint64_t{dropped} << kIndexShift;
  int slot = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    if (i == dropped) continue;
    const double k = std::clamp(std::round(c[i] / kComponentStep) + kComponentZero, 0.0, 2.0 * kComponentZero);
    word |= static_cast<std::uint64_t>(k) << (kComponentBits * slot);
    ++slot;
  }
  return word;
}

// The centre's offset from the origin in cm, or nothing when an axis is beyond +-327.67 m.
std::optional<std::array<std::int16_t, 3>> centreOffsetCm(const Eigen::Vector3d& centre, const CompactOrigin& origin) {
  const std::array<std::int32_t, 3> origin_cm = {origin.x_cm, origin.y_cm, origin.z_cm};
  std::array<std::int16_t, 3> offset{};
  for (int i = 0; i < 3; ++i) {
    const double cm = std::round(centre[i] * 100.0 - static_cast<double>(origin_cm[static_cast<std::size_t>(i)]));
    if (!(std::abs(cm) <= kCentreLimitCm)) return std::nullopt;
    offset[static_cast<std::size_t>(i)] = static_cast<std::int16_t>(cm);
  }
  return offset;
}

// The fields of e, or nothing when e does not fit (see fitsCompact).
std::optional<CompactFields> quantise(const Ellipsoid& e, const CompactOrigin& origin) {
  if (!e.center.allFinite() || !e.shape.allFinite()) return std::nullopt;
  if (e.point_count > kU16Max || e.id.index > kU16Max) return std::nullopt;
  const double scale = e.shape.cwiseAbs().maxCoeff();
  if (!((e.shape - e.shape.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale)) return std::nullopt;

  CompactFields fields;
  const auto offset = centreOffsetCm(e.center, origin);
  if (!offset) return std::nullopt;
  fields.centre_cm = *offset;

  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(0.5 * (e.shape + e.shape.transpose()));
  if (solver.info() != Eigen::Success) return std::nullopt;
  const Eigen::Vector3d eigenvalues = solver.eigenvalues();  // ascending
  if (!(eigenvalues[0] > 0.0)) return std::nullopt;
  for (int i = 0; i < 3; ++i) {
    const double a = std::sqrt(eigenvalues[i]);
    // What rounds to 1 .. 65,535 mm fits: a decoded 65.535 m axis may come back a hair above it.
    if (!(a >= kCompactMinSemiAxisM && a < kCompactMaxSemiAxisM + kCompactSemiAxisErrorM)) return std::nullopt;
    // a = 0.5 mm may land a hair below 0.5 in mm; the clamp keeps it within half a step.
    fields.semi_axes_mm[i] = static_cast<std::uint16_t>(std::clamp(std::round(a * 1000.0), 1.0, 65535.0));
  }
  fields.orientation = packOrientation(canonicalRotation(solver.eigenvectors()));
  fields.point_count = static_cast<std::uint16_t>(e.point_count);
  fields.index = static_cast<std::uint16_t>(e.id.index);
  return fields;
}

}  // namespace

CompactOrigin compactOriginNear(const Eigen::Vector3d& p) {
  auto cm = [](double metres) {
    if (!std::isfinite(metres)) return std::int32_t{0};
    return static_cast<std::int32_t>(std::clamp(std::round(metres * 100.0),
                                                static_cast<double>(std::numeric_limits<std::int32_t>::min()),
                                                static_cast<double>(std::numeric_limits<std::int32_t>::max())));
  };
  return {cm(p.x()), cm(p.y()), cm(p.z())};
}

bool fitsCompact(const Ellipsoid& e, const CompactOrigin& origin) { return quantise(e, origin).has_value(); }

bool compactCentreFits(const Eigen::Vector3d& centre, const CompactOrigin& origin) {
  return centreOffsetCm(centre, origin).has_value();
}

bool appendCompact(const Ellipsoid& e, const CompactOrigin& origin, std::string& out, CompactIndex index) {
  const std::optional<CompactFields> fields = quantise(e, origin);
  if (!fields) return false;
  for (const std::int16_t c : fields->centre_cm) putU16(out, static_cast<std::uint16_t>(c));
  for (const std::uint16_t a : fields->semi_axes_mm) putU16(out, a);
  putLittleEndian(out, fields->orientation, 6);
  putU16(out, fields->point_count);
  if (index == CompactIndex::kInRecord) putU16(out, fields->index);
  return true;
}

Expected<Ellipsoid> decodeCompact(std::string_view record, const CompactOrigin& origin, std::uint32_t node,
                                  std::uint64_t frame, std::optional<std::uint32_t> implicit_index) {
  const std::size_t expected = compactRecordBytes(implicit_index ? CompactIndex::kImplicit : CompactIndex::kInRecord);
  if (record.size() != expected) {
    const std::string kind = implicit_index ? "a compact ellipsoid record without its index" : "a compact ellipsoid record";
    return invalidArgument(kind + " has " + std::to_string(expected) + " bytes, got " + std::to_string(record.size()));
  }
  Ellipsoid e;
  e.id = EllipsoidId{node, frame, implicit_index ? *implicit_index : getU16(record, 20)};
  e.point_count = getU16(record, 18);
  auto refuse = [&e](const std::string& what) {
    return invalidArgument("compact ellipsoid " + toString(e.id) + ": " + what);
  };

  const std::uint64_t word = getLittleEndian(record, kOrientationOffset, 6);
  if ((word >> kReservedBit) & 1U) return refuse("orientation: the reserved bit 47 is set");
  Eigen::Vector3d semi_axes;
  for (int i = 0; i < 3; ++i) {
    const std::uint16_t mm = getU16(record, 6 + 2 * static_cast<std::size_t>(i));
    if (mm == 0) {
      return refuse("semi-axis " + std::to_string(i) + " is 0 mm (must be 1 .. 65535 mm)");
    }
    semi_axes[i] = mm / 1000.0;
  }
  const auto dropped = static_cast<std::size_t>((word >> kIndexShift) & 3U);
  std::array<double, 4> c{};
  double kept_norm2 = 0.0;
  int slot = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    if (i == dropped) continue;
    const auto k = static_cast<double>((word >> (kComponentBits * slot)) & kComponentMask);
    c[i] = (k - kComponentZero) * kComponentStep;
    kept_norm2 += c[i] * c[i];
    ++slot;
  }
  if (kept_norm2 > 1.0 + kQuaternionNormTolerance) {
    return refuse("orientation: the three stored quaternion components have squared norm " +
                  std::to_string(kept_norm2) + ", more than 1");
  }
  c[dropped] = std::sqrt(std::max(0.0, 1.0 - kept_norm2));
  // |q| >= 1 here (the dropped component tops it up to 1, or the kept three exceed 1 by a hair).
  const Eigen::Quaterniond q = Eigen::Quaterniond(c[0], c[1], c[2], c[3]).normalized();
  const Eigen::Matrix3d r = q.toRotationMatrix();
  const Eigen::Matrix3d shape = r * semi_axes.cwiseAbs2().asDiagonal() * r.transpose();
  e.shape = 0.5 * (shape + shape.transpose());  // a + b == b + a: exactly symmetric

  const std::array<std::int32_t, 3> origin_cm = {origin.x_cm, origin.y_cm, origin.z_cm};
  for (int i = 0; i < 3; ++i) {
    const auto offset_cm = static_cast<std::int16_t>(getU16(record, 2 * static_cast<std::size_t>(i)));
    e.center[i] = static_cast<double>(std::int64_t{origin_cm[i]} + offset_cm) / 100.0;
  }
  return e;
}

Expected<std::vector<Ellipsoid>> decodeCompactBlock(std::string_view records, const CompactOrigin& origin,
                                                    std::uint32_t node, std::uint64_t frame,
                                                    std::optional<std::uint32_t> first_index) {
  const std::size_t size = compactRecordBytes(first_index ? CompactIndex::kImplicit : CompactIndex::kInRecord);
  if (records.size() % size != 0) {
    return invalidArgument("a compact ellipsoid block has " + std::to_string(records.size()) +
                           " bytes, not a multiple of " + std::to_string(size));
  }
  const std::size_t count = records.size() / size;
  if (first_index && count > 0 && count - 1 > std::numeric_limits<std::uint32_t>::max() - *first_index) {
    return invalidArgument("a compact ellipsoid block of " + std::to_string(count) + " records from index " +
                           std::to_string(*first_index) + " runs past the last index, 2^32 - 1");
  }
  std::vector<Ellipsoid> ellipsoids;
  ellipsoids.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto index = first_index ? std::optional<std::uint32_t>(*first_index + static_cast<std::uint32_t>(i)) : std::nullopt;
    Expected<Ellipsoid> e = decodeCompact(records.substr(i * size, size), origin, node, frame, index);
    if (!e) {
      return invalidArgument("record " + std::to_string(i) + " of " + std::to_string(count) + ": " +
                             e.error().message);
    }
    ellipsoids.push_back(std::move(e).value());
  }
  return ellipsoids;
}

}  // namespace fogmap
