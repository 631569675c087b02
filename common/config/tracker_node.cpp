#include "common/config/tracker_node.hpp"

#include "common/config/optional_section_impl.hpp"

namespace fogmap {

template class OptionalSection<TrackerNodeConfig>;

const char* trackerInputName(TrackerInput input) {
  switch (input) {
    case TrackerInput::kGlobalMap:
      return "global_map";
    case TrackerInput::kCentroids:
      return "centroids";
  }
  return "unknown";
}

Expected<TrackerInput> parseTrackerInput(const std::string& name) {
  if (name == "global_map") return TrackerInput::kGlobalMap;
  if (name == "centroids") return TrackerInput::kCentroids;
  return invalidArgument("must be global_map (the root's global map) or centroids (its edges' displacement centroids), got '" +
                         name + "'");
}

}  // namespace fogmap
