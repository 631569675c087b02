#pragma once
// Loopback ports for tests, chosen free at run time: the one implementation is fogctl's.
#include "tools/fogctl/free_ports.hpp"

namespace fogmap::test_support {

using cli::freePorts;
using cli::useFreePorts;

}  // namespace fogmap::test_support
