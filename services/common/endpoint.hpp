#pragma once
// The one way a fogmap address is written: "host:port", for gRPC targets and listening addresses
// and for /metrics alike.
#include <string>
#include <string_view>

namespace fogmap {

// "host:port"; an IPv6 literal host gets its brackets ("[::1]:50051"), a host already in brackets
// keeps them.
std::string endpoint(std::string_view host, unsigned port);

}  // namespace fogmap
