#pragma once
// An image file's format and size, read from its header without decoding it: what a frame source
// checks against the camera's pixel limit before it lets a decoder allocate anything. The formats
// are those OpenCV would decode from a camera's image files: PNG (IHDR), JPEG (the first SOFn
// frame header), BMP (the DIB header) and PNM (P1 to P7). Pure: bytes in, values out.
#include <cstdint>
#include <optional>
#include <span>

#include "common/base/status.hpp"

namespace fogmap {

enum class ImageFormat { kPng, kJpeg, kBmp, kPnm };
const char* imageFormatName(ImageFormat format);  // "PNG", "JPEG", "BMP", "PNM"

struct ImageHeader {
  ImageFormat format = ImageFormat::kPng;
  std::uint32_t width = 0;   // pixels, > 0
  std::uint32_t height = 0;  // pixels, > 0
  std::uint64_t pixels() const { return static_cast<std::uint64_t>(width) * height; }
};

// The format whose signature `bytes` (a file's first bytes) start with; nullopt for any other.
std::optional<ImageFormat> imageFormatOf(std::span<const std::uint8_t> bytes);

// The header of the image in `bytes` (the whole file, or at least up to its size fields: a JPEG's
// frame header may follow kilobytes of metadata). An error saying what is wrong when the format is
// unknown, or the header is cut short, malformed or gives a zero size. Never reads past `bytes`.
Expected<ImageHeader> readImageHeader(std::span<const std::uint8_t> bytes);

}  // namespace fogmap
