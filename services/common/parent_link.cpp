#include "services/common/parent_link.hpp"
