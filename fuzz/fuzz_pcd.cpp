// libFuzzer target: the PCD reader (ascii, binary, binary_compressed; fogmap's header and size
// checks, then PCL's decoding) over arbitrary bytes, dropping and keeping non-finite points.
// fogmap's checks must name every problem: an input that only PCL turns down is a finding.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz/fuzz_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fogmap;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  for (const bool keep : {false, true}) {
    const ReadLimits limits{.keep_non_finite = keep};
    const Expected<LoadedCloud> loaded = parsePcd(bytes, "fuzz.pcd", limits);
    fuzz::checkLoaded(loaded, "fuzz.pcd", limits);
    if (!loaded) {
      const std::string& message = loaded.error().message;
      for (const char* fallback : {"PCL could not read", "PCL read the PCD header differently",
                                   "PCL decoded the PCD file differently"}) {
        fuzz::check(!message.starts_with(std::string("fuzz.pcd: ") + fallback), "fogmap's checks name the problem, not PCL");
      }
    }
  }
  return 0;
}
