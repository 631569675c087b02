#pragma once
// Loopback ports for tests, chosen free at run time: the one implementation is fogctl's.
#include "harness/free_ports.hpp"

namespace fogmap::test_support {

using harness::freePorts;
using harness::useFreePorts;

}  // namespace fogmap::test_support
