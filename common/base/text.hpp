#pragma once
// Numbers in messages.
#include <string>

namespace fogmap {

// The shortest readable form of a number for error messages ("0.2", "1e-07", "15"), unlike
// std::to_string's fixed "%f".
std::string readableNumber(double value);

}  // namespace fogmap
