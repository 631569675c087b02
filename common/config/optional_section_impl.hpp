#pragma once
// OptionalSection's members, for the one .cpp per section that instantiates them where the
// section's type is complete (`template class OptionalSection<CameraNodeConfig>;`).
#include <memory>
#include <utility>

#include "common/config/optional_section.hpp"

namespace fogmap {

template <class T>
OptionalSection<T>::OptionalSection() = default;

template <class T>
OptionalSection<T>::OptionalSection(const OptionalSection& other)
    : value_(other.value_ ? std::make_unique<T>(*other.value_) : nullptr) {}

template <class T>
OptionalSection<T>::OptionalSection(OptionalSection&& other) noexcept = default;

template <class T>
OptionalSection<T>& OptionalSection<T>::operator=(const OptionalSection& other) {
  if (this != &other) value_ = other.value_ ? std::make_unique<T>(*other.value_) : nullptr;
  return *this;
}

template <class T>
OptionalSection<T>& OptionalSection<T>::operator=(OptionalSection&& other) noexcept = default;

template <class T>
OptionalSection<T>& OptionalSection<T>::operator=(T value) {
  value_ = std::make_unique<T>(std::move(value));
  return *this;
}

template <class T>
OptionalSection<T>::~OptionalSection() = default;

template <class T>
void OptionalSection<T>::reset() noexcept {
  value_.reset();
}

}  // namespace fogmap
