#pragma once
// What an obstacle is (issue "Shape, class and vehicles"): the classes fogmap tells apart, and a
// class with its confidence as one sensor's classifier or a whole object's views say it.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

namespace fogmap {

enum class ObjectClass : std::uint8_t { kOther = 0, kPerson, kCar, kTruckOrBus, kCyclist, kPole };
inline constexpr std::size_t kObjectClassCount = 6;
// "other", "person", "car", "truck_or_bus", "cyclist", "pole".
std::string_view objectClassName(ObjectClass object_class);
std::optional<ObjectClass> parseObjectClass(std::string_view name);
// Cars, trucks and buses: what the tracker follows with a vehicle model.
inline constexpr bool isVehicle(ObjectClass c) { return c == ObjectClass::kCar || c == ObjectClass::kTruckOrBus; }

struct ObjectLabel {
  ObjectClass object_class = ObjectClass::kOther;
  double confidence = 0.0;  // in [0, 1]
  bool operator==(const ObjectLabel&) const = default;
};

}  // namespace fogmap
