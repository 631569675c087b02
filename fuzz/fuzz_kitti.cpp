// libFuzzer target: the KITTI .bin reader (16-byte records) over arbitrary bytes, dropping and keeping
// non-finite points. Every whole record is a point, kept or counted as dropped.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz/fuzz_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fogmap;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  for (const bool keep : {false, true}) {
    const ReadLimits limits{.keep_non_finite = keep};
    const Expected<LoadedCloud> loaded = parseKittiBin(bytes, "fuzz.bin", limits);
    fuzz::checkLoaded(loaded, "fuzz.bin", limits);
    if (loaded) {
      fuzz::check(size % 16 == 0 && loaded->points.size() + loaded->dropped_non_finite == size / 16,
                  "every record is one point");
    }
  }
  return 0;
}
