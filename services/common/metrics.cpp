#include "services/common/metrics.hpp"
