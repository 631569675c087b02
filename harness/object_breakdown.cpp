#include "harness/object_breakdown.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <set>
#include <sstream>
#include <utility>

namespace fogmap::harness {
namespace {

const sim::SceneObject* findObject(const sim::Scene& scene, std::int64_t id) {
  for (const auto& o : scene.objects) {
    if (static_cast<std::int64_t>(o.id) == id) return &o;
  }
  return nullptr;
}

Error unknownObject(const sim::Scene& scene, std::int64_t id) {
  return invalidArgument("true object " + std::to_string(id) + " is not an object of the scene " + scene.name);
}

void add(std::map<std::string, ObjectMatch>& sums, const std::string& key, const ObjectOutcome& o) {
  ObjectMatch& m = sums[key];
  ++m.objects_true;
  m.found_whole += o.found_whole ? 1 : 0;
  m.split += o.split ? 1 : 0;
  m.merged += o.merged ? 1 : 0;
  m.missed += o.missed ? 1 : 0;
}

Json bandsReport(const ObjectBreakdown& b) {
  Json j = Json::object();
  for (const char* band : kRangeBands) {
    const auto it = b.by_range_band.find(band);
    j[band] = objectMatchReport(it == b.by_range_band.end() ? ObjectMatch{} : it->second);
  }
  return j;
}

Json kindsReport(const ObjectBreakdown& b) {
  Json j = Json::object();
  for (const auto& [kind, m] : b.by_kind) j[kind] = objectMatchReport(m);
  return j;
}

std::string tableText(const std::string& system, const ObjectBreakdown& b) {
  std::ostringstream out;
  char line[160];
  std::snprintf(line, sizeof(line), "  %-18s %7s %7s %7s %7s %7s\n", system.c_str(), "true", "whole", "split", "merged", "missed");
  out << line;
  const auto row = [&](const std::string& name, const ObjectMatch& m) {
    std::snprintf(line, sizeof(line), "    %-16s %7zu %7zu %7zu %7zu %7zu\n", name.c_str(), m.objects_true, m.found_whole, m.split,
                  m.merged, m.missed);
    out << line;
  };
  for (const char* band : kRangeBands) {
    const auto it = b.by_range_band.find(band);
    row(std::string(band) + " m", it == b.by_range_band.end() ? ObjectMatch{} : it->second);
  }
  for (const auto& [kind, m] : b.by_kind) row(kind, m);
  return out.str();
}

std::string cell(const ObjectMatch& m) {
  return std::to_string(m.found_whole) + " / " + std::to_string(m.split) + " / " + std::to_string(m.merged) + " / " +
         std::to_string(m.missed) + " of " + std::to_string(m.objects_true);
}

ObjectMatch countOf(const std::map<std::string, ObjectMatch>& sums, const std::string& key) {
  const auto it = sums.find(key);
  return it == sums.end() ? ObjectMatch{} : it->second;
}

}  // namespace

std::string rangeBand(double distance_m) {
  if (distance_m < 10.0) return kRangeBands[0];
  if (distance_m < 20.0) return kRangeBands[1];
  if (distance_m < 40.0) return kRangeBands[2];
  return kRangeBands[3];  // also NaN and infinity
}

double nearestLidarDistance(const sim::Scene& scene, const Eigen::Vector2d& xy) {
  double nearest = std::numeric_limits<double>::infinity();
  for (const auto& l : scene.lidars) nearest = std::min(nearest, (l.pose.translation().head<2>() - xy).norm());
  return nearest;
}

std::string objectKind(const sim::SceneObject& object) { return object.label.empty() ? kOtherKind : object.label; }

ObjectBreakdown emptyBreakdown(const sim::Scene& scene) {
  ObjectBreakdown out;
  for (const char* band : kRangeBands) out.by_range_band[band] = {};
  for (const auto& o : scene.objects) out.by_kind[objectKind(o)] = {};
  return out;
}

Expected<ObjectBreakdown> breakDownObjects(const sim::Scene& scene, double time_s, std::span<const ObjectOutcome> outcomes) {
  ObjectBreakdown out = emptyBreakdown(scene);
  for (const auto& o : outcomes) {
    const sim::SceneObject* object = findObject(scene, o.true_object);
    if (object == nullptr) return unknownObject(scene, o.true_object);
    add(out.by_range_band, rangeBand(nearestLidarDistance(scene, sim::poseAt(*object, time_s).xy)), o);
    add(out.by_kind, objectKind(*object), o);
  }
  return out;
}

void addObjectMatch(ObjectMatch& sum, const ObjectMatch& m) {
  sum.objects_true += m.objects_true;
  sum.found_whole += m.found_whole;
  sum.split += m.split;
  sum.merged += m.merged;
  sum.missed += m.missed;
}

void addBreakdown(ObjectBreakdown& sum, const ObjectBreakdown& frame) {
  for (const auto& [band, m] : frame.by_range_band) addObjectMatch(sum.by_range_band[band], m);
  for (const auto& [kind, m] : frame.by_kind) addObjectMatch(sum.by_kind[kind], m);
}

Expected<std::vector<Eigen::Vector2d>> missedCentres(const sim::Scene& scene, double time_s,
                                                     std::span<const ObjectOutcome> outcomes) {
  std::vector<Eigen::Vector2d> out;
  for (const auto& o : outcomes) {
    if (!o.missed) continue;
    const sim::SceneObject* object = findObject(scene, o.true_object);
    if (object == nullptr) return unknownObject(scene, o.true_object);
    out.push_back(sim::poseAt(*object, time_s).xy);
  }
  return out;
}

Json objectMatchReport(const ObjectMatch& m) {
  Json j;
  j["true"] = m.objects_true;
  j["found_whole"] = m.found_whole;
  j["split"] = m.split;
  j["merged"] = m.merged;
  j["missed"] = m.missed;
  return j;
}

Json rangeBandReport(const ObjectBreakdown& madc, const ObjectBreakdown& baseline) {
  Json j;
  j["madc"] = bandsReport(madc);
  j["baseline"] = bandsReport(baseline);
  return j;
}

Json kindReport(const ObjectBreakdown& madc, const ObjectBreakdown& baseline) {
  Json j;
  j["madc"] = kindsReport(madc);
  j["baseline"] = kindsReport(baseline);
  return j;
}

std::string objectBreakdownText(const ObjectBreakdown& madc, const ObjectBreakdown& baseline) {
  return "  true objects by range band (horizontal distance to the nearest LiDAR) and by kind, all frames:\n" +
         tableText("MAD-C", madc) + tableText("baseline", baseline);
}

std::string objectBreakdownMarkdown(const std::string& configuration_header, std::span<const BreakdownRow> rows) {
  std::set<std::string> kinds;
  for (const auto& r : rows) {
    for (const ObjectBreakdown* b : {r.madc, r.baseline}) {
      if (b == nullptr) continue;
      for (const auto& [kind, m] : b->by_kind) kinds.insert(kind);
    }
  }
  std::ostringstream md;
  const auto table = [&](const std::vector<std::string>& columns, const std::string& suffix, bool bands) {
    md << "| " << configuration_header << " | system |";
    for (const auto& c : columns) md << " " << c << suffix << " |";
    md << "\n|---|---|";
    for (std::size_t i = 0; i < columns.size(); ++i) md << "---|";
    md << "\n";
    for (const auto& r : rows) {
      for (const auto& [system, b] : {std::pair<const char*, const ObjectBreakdown*>{"MAD-C", r.madc}, {"baseline", r.baseline}}) {
        if (b == nullptr) continue;
        md << "| " << r.configuration << " | " << system << " |";
        for (const auto& c : columns) md << " " << cell(countOf(bands ? b->by_range_band : b->by_kind, c)) << " |";
        md << "\n";
      }
    }
  };
  table(std::vector<std::string>(kRangeBands.begin(), kRangeBands.end()), " m", true);
  md << "\n";
  table(std::vector<std::string>(kinds.begin(), kinds.end()), "", false);
  return md.str();
}

}  // namespace fogmap::harness
