#include "common/geometry/compact_view.hpp"

#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>

#include "common/base/little_endian.hpp"

namespace fogmap {

namespace {

constexpr unsigned kBoxBit = 1U;
constexpr unsigned kAnchorShift = 1U;
constexpr unsigned kAnchorMask = 0xFU;
constexpr unsigned kClassShift = 5U;
constexpr unsigned kClassMask = 0x7U;
constexpr unsigned kMaxAnchor = static_cast<unsigned>(BoxAnchor::kRearRight);
constexpr double kOffsetLimitCm = 32767.0;
constexpr double kSideLimitCm = 65535.0;
constexpr double kYawSteps = 65536.0;
constexpr std::size_t kBoxBytes = 14;

struct BoxFields {
  std::int16_t centre[3] = {0, 0, 0};
  std::uint16_t sides[3] = {0, 0, 0};
  std::uint16_t yaw = 0;
};

double roundedCm(double metres) { return std::round(metres * 100.0); }

std::optional<BoxFields> quantiseBox(const OrientedBox& box, const Eigen::Vector3d& ellipsoid_centre) {
  BoxFields f;
  if (!box.centre.allFinite() || !ellipsoid_centre.allFinite()) return std::nullopt;
  for (int i = 0; i < 3; ++i) {
    const double offset = roundedCm(box.centre[i]) - roundedCm(ellipsoid_centre[i]);
    if (!(std::abs(offset) <= kOffsetLimitCm)) return std::nullopt;
    f.centre[i] = static_cast<std::int16_t>(offset);
  }
  const double sides[3] = {box.length, box.width, box.height};
  for (int i = 0; i < 3; ++i) {
    const double cm = roundedCm(sides[i]);
    if (!(cm >= 0.0 && cm <= kSideLimitCm)) return std::nullopt;
    f.sides[i] = static_cast<std::uint16_t>(cm);
  }
  constexpr double pi = std::numbers::pi;
  if (!(box.yaw >= -0.5 * pi && box.yaw < 0.5 * pi)) return std::nullopt;
  const double k = std::round((box.yaw + 0.5 * pi) / pi * kYawSteps);
  f.yaw = static_cast<std::uint16_t>(k >= kYawSteps ? 0.0 : k);  // pi/2 - a hair wraps to -pi/2
  if (static_cast<unsigned>(box.anchor) > kMaxAnchor) return std::nullopt;
  return f;
}

bool labelFits(const ObjectLabel& label) {
  return static_cast<std::size_t>(label.object_class) < kObjectClassCount && label.confidence >= 0.0 &&
         label.confidence <= 1.0;
}

}  // namespace

bool viewFitsCompact(const Ellipsoid& e) {
  if (e.box && !quantiseBox(*e.box, e.center)) return false;
  return !e.label || labelFits(*e.label);
}

bool appendCompactView(const Ellipsoid& e, std::string& out) {
  std::optional<BoxFields> fields;
  if (e.box && !(fields = quantiseBox(*e.box, e.center))) return false;
  if (e.label && !labelFits(*e.label)) return false;
  unsigned flags = 0;
  if (e.box) flags |= kBoxBit | (static_cast<unsigned>(e.box->anchor) << kAnchorShift);
  if (e.label) flags |= (static_cast<unsigned>(e.label->object_class) + 1U) << kClassShift;
  out.push_back(static_cast<char>(flags));
  if (e.label) out.push_back(static_cast<char>(static_cast<unsigned>(std::round(e.label->confidence * 255.0))));
  if (fields) {
    const BoxFields& f = *fields;
    for (const std::int16_t c : f.centre) putU16(out, static_cast<std::uint16_t>(c));
    for (const std::uint16_t s : f.sides) putU16(out, s);
    putU16(out, f.yaw);
  }
  return true;
}

Status readCompactView(std::string_view entries, std::size_t& offset, Ellipsoid& e) {
  auto refuse = [&](const std::string& what) {
    return invalidArgument("view of ellipsoid " + toString(e.id) + ": " + what);
  };
  if (offset >= entries.size()) return refuse("the entries end before this one");
  const auto flags = static_cast<unsigned>(static_cast<unsigned char>(entries[offset]));
  const bool has_box = (flags & kBoxBit) != 0;
  const unsigned anchor = (flags >> kAnchorShift) & kAnchorMask;
  const unsigned class_code = (flags >> kClassShift) & kClassMask;
  if (anchor > kMaxAnchor) return refuse("anchor " + std::to_string(anchor) + " (0 to 8)");
  if (!has_box && anchor != 0) return refuse("an anchor without a box");
  if (class_code > kObjectClassCount) return refuse("class code " + std::to_string(class_code) + " (0 to 6)");
  const std::size_t size = 1 + (class_code != 0 ? 1 : 0) + (has_box ? kBoxBytes : 0);
  if (entries.size() - offset < size) {
    return refuse("the entry needs " + std::to_string(size) + " bytes, " + std::to_string(entries.size() - offset) +
                  " are left");
  }
  std::size_t at = offset + 1;
  e.label.reset();
  e.box.reset();
  if (class_code != 0) {
    e.label = ObjectLabel{static_cast<ObjectClass>(class_code - 1),
                          static_cast<double>(static_cast<unsigned char>(entries[at])) / 255.0};
    ++at;
  }
  if (has_box) {
    OrientedBox box;
    for (int i = 0; i < 3; ++i) {
      const auto offset_cm = static_cast<std::int16_t>(getU16(entries, at + 2 * static_cast<std::size_t>(i)));
      box.centre[i] = (roundedCm(e.center[i]) + offset_cm) / 100.0;
    }
    at += 6;
    box.length = getU16(entries, at) / 100.0;
    box.width = getU16(entries, at + 2) / 100.0;
    box.height = getU16(entries, at + 4) / 100.0;
    box.yaw = -0.5 * std::numbers::pi + getU16(entries, at + 6) * std::numbers::pi / kYawSteps;
    box.anchor = static_cast<BoxAnchor>(anchor);
    at += 8;
    e.box = box;
  }
  offset = at;
  return {};
}

}  // namespace fogmap
