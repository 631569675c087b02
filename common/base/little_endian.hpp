#pragma once
// Little-endian fixed-width fields, the byte order of every packed field fogmap puts on the wire
// (compact ellipsoid records, compact views, point chunks, labels), whatever the host's order.
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace fogmap {

// Appends the low `count` bytes of `v` (1 to 8), least significant first.
inline void putLittleEndian(std::string& out, std::uint64_t v, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFFU));
}

// Reads `count` bytes (1 to 8) at `offset`, least significant first; the caller has checked that
// they are there.
inline std::uint64_t getLittleEndian(std::string_view bytes, std::size_t offset, std::size_t count) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < count; ++i) v |= std::uint64_t{static_cast<unsigned char>(bytes[offset + i])} << (8 * i);
  return v;
}

// On a little-endian host (all fogmap builds for) a field is one copy.
template <typename T>
inline void putField(std::string& out, T v) {
  if constexpr (std::endian::native == std::endian::little) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    out.append(b, sizeof(T));
  } else {
    putLittleEndian(out, v, sizeof(T));
  }
}
template <typename T>
inline T getField(std::string_view bytes, std::size_t offset) {
  T v{};
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(&v, bytes.data() + offset, sizeof(T));
  } else {
    v = static_cast<T>(getLittleEndian(bytes, offset, sizeof(T)));
  }
  return v;
}

inline void putU16(std::string& out, std::uint16_t v) { putField(out, v); }
inline std::uint16_t getU16(std::string_view bytes, std::size_t offset) { return getField<std::uint16_t>(bytes, offset); }
inline void putU32(std::string& out, std::uint32_t v) { putField(out, v); }
inline std::uint32_t getU32(std::string_view bytes, std::size_t offset) { return getField<std::uint32_t>(bytes, offset); }
inline void putFloat(std::string& out, float f) { putU32(out, std::bit_cast<std::uint32_t>(f)); }
inline float getFloat(std::string_view bytes, std::size_t offset) { return std::bit_cast<float>(getU32(bytes, offset)); }

}  // namespace fogmap
