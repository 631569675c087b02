#include "common/geometry/object_class.hpp"

#include <array>

namespace fogmap {

namespace {
constexpr std::array<std::string_view, kObjectClassCount> kClassNames = {"other",        "person",  "car",
                                                                         "truck_or_bus", "cyclist", "pole"};
}  // namespace

std::string_view objectClassName(ObjectClass object_class) {
  const auto index = static_cast<std::size_t>(object_class);
  return index < kClassNames.size() ? kClassNames[index] : "other";
}

std::optional<ObjectClass> parseObjectClass(std::string_view name) {
  for (std::size_t k = 0; k < kClassNames.size(); ++k) {
    if (kClassNames[k] == name) return static_cast<ObjectClass>(k);
  }
  return std::nullopt;
}

}  // namespace fogmap
