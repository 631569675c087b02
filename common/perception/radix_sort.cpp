#include "common/perception/radix_sort.hpp"

#include <cstddef>

namespace fogmap {

void radixSort(std::vector<std::uint64_t>& words, int shift, int key_bits) {
  constexpr int kMaxDigitBits = 11;
  const int passes = (key_bits + kMaxDigitBits - 1) / kMaxDigitBits;
  const int digit_bits = (key_bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t{1} << digit_bits;
  const std::uint64_t digit_mask = buckets - 1;
  std::vector<std::uint32_t> offsets(buckets * static_cast<std::size_t>(passes), 0U);
  for (const auto w : words) {
    for (int p = 0; p < passes; ++p) {
      ++offsets[static_cast<std::size_t>(p) * buckets + ((w >> (shift + p * digit_bits)) & digit_mask)];
    }
  }
  std::vector<std::uint64_t> tmp(words.size());
  for (int p = 0; p < passes; ++p) {
    std::uint32_t* offset = &offsets[static_cast<std::size_t>(p) * buckets];
    std::uint32_t sum = 0;
    for (std::size_t d = 0; d < buckets; ++d) {
      const auto count = offset[d];
      offset[d] = sum;
      sum += count;
    }
    const int digit_shift = shift + p * digit_bits;
    for (const auto w : words) tmp[offset[(w >> digit_shift) & digit_mask]++] = w;
    words.swap(tmp);
  }
}

}  // namespace fogmap
