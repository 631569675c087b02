#include "common/config/camera_node.hpp"

#include "common/config/optional_section_impl.hpp"

namespace fogmap {

template class OptionalSection<CameraNodeConfig>;

}  // namespace fogmap
