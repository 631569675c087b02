#pragma once
// How large a camera frame may be (topology `camera.max_image_pixels`). A frame source refuses a
// larger image from its header, before a decoder allocates it: a 20,000 x 20,000 PNG of one colour
// is a few hundred kilobytes on disk and 1.2 GB decoded, and takes tens of seconds to decode.
#include <cstdint>

namespace fogmap::camera {

// 4096 x 4096 (16.8 MP): room for 4K video (3840 x 2160) and 16 MP stills; a KITTI frame (1242 x
// 375) is 0.47 MP. Decoded as 8-bit BGR such a frame is 48 MiB.
inline constexpr std::uint64_t kDefaultMaxImagePixels = 4096ULL * 4096ULL;
// The largest limit a topology may set: 16384 x 16384 (768 MiB decoded).
inline constexpr std::uint64_t kMaxImagePixelsBound = 16384ULL * 16384ULL;

}  // namespace fogmap::camera
