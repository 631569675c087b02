// The one way an address is written: host:port, IPv6 literals in brackets.
#include <gtest/gtest.h>

#include "services/common/endpoint.hpp"

namespace fogmap {
namespace {

TEST(Endpoint, IsHostColonPortWithIpv6LiteralsInBrackets) {
  EXPECT_EQ(endpoint("127.0.0.1", 50051), "127.0.0.1:50051");
  EXPECT_EQ(endpoint("0.0.0.0", 0), "0.0.0.0:0");
  EXPECT_EQ(endpoint("sink.local", 9100), "sink.local:9100");
  EXPECT_EQ(endpoint("::1", 50051), "[::1]:50051");
  EXPECT_EQ(endpoint("fe80::1%eth0", 7), "[fe80::1%eth0]:7");
  EXPECT_EQ(endpoint("[::1]", 50051), "[::1]:50051") << "already in brackets";
}

}  // namespace
}  // namespace fogmap
