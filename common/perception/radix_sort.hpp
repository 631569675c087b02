#pragma once
// The radix sort both clusterings build on (the exact mode's grid, the sensor-aware range image).
#include <cstdint>
#include <vector>

namespace fogmap {

// LSD radix sort of 64-bit words by their bits [shift, shift + key_bits): as few passes of at
// most 11 bits as cover the key, every histogram counted in one read. Stable.
void radixSort(std::vector<std::uint64_t>& words, int shift, int key_bits);

}  // namespace fogmap
