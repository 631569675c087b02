// libFuzzer target: the nuScenes .pcd.bin reader (20-byte records) over arbitrary bytes, dropping and keeping
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
    const Expected<LoadedCloud> loaded = parseNuscenesBin(bytes, "fuzz.pcd.bin", limits);
    fuzz::checkLoaded(loaded, "fuzz.pcd.bin", limits);
    if (loaded) {
      fuzz::check(size % 20 == 0 && loaded->points.size() + loaded->dropped_non_finite == size / 20,
                  "every record is one point");
    }
  }
  return 0;
}
