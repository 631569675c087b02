#include "common/config/displacement_node.hpp"

#include "common/config/optional_section_impl.hpp"

namespace fogmap {

template class OptionalSection<DisplacementNodeConfig>;

}  // namespace fogmap
