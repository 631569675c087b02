#pragma once
// An optional section of a node (`camera:`, `tracker:`, `displacement:`) that topology.hpp holds
// without knowing its type: the value lives on the heap, so the model needs only a declaration and
// its readers need neither the camera's nor the tracker's headers. It reads like std::optional
// (has_value, bool, *, ->, assignment from a value); only code that looks inside includes the
// section's header (common/config/camera_node.hpp, tracker_node.hpp, displacement_node.hpp), whose
// .cpp instantiates the members (optional_section_impl.hpp).
#include <memory>

namespace fogmap {

template <class T>
class OptionalSection {
 public:
  OptionalSection();  // empty
  OptionalSection(const OptionalSection& other);
  OptionalSection(OptionalSection&& other) noexcept;
  OptionalSection& operator=(const OptionalSection& other);
  OptionalSection& operator=(OptionalSection&& other) noexcept;
  // Holds a copy of `value` (present from now on).
  OptionalSection& operator=(T value);
  ~OptionalSection();

  bool has_value() const noexcept { return value_ != nullptr; }
  explicit operator bool() const noexcept { return has_value(); }
  // The value; only when has_value().
  T& operator*() noexcept { return *value_.get(); }
  const T& operator*() const noexcept { return *value_.get(); }
  T* operator->() noexcept { return value_.get(); }
  const T* operator->() const noexcept { return value_.get(); }
  void reset() noexcept;

 private:
  std::unique_ptr<T> value_;
};

}  // namespace fogmap
