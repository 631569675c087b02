#include "services/common/endpoint.hpp"

namespace fogmap {

std::string endpoint(std::string_view host, unsigned port) {
  // A colon can only be part of an IPv6 literal: names and IPv4 addresses have none.
  const bool bracket = host.find(':') != std::string_view::npos && !host.starts_with('[');
  std::string out;
  out.reserve(host.size() + 8);
  if (bracket) out += '[';
  out += host;
  if (bracket) out += ']';
  out += ':';
  out += std::to_string(port);
  return out;
}

}  // namespace fogmap
