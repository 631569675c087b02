// The wire's byte order (common/base/little_endian.hpp), against bytes written out by hand.
#include "common/base/little_endian.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <string>

namespace fogmap {
namespace {

TEST(LittleEndian, FieldsGoLeastSignificantByteFirst) {
  std::string out;
  putU16(out, 0x1234);
  putU32(out, 0xA1B2C3D4U);
  putLittleEndian(out, 0x0000'0605'0403'0201ULL, 6);
  EXPECT_EQ(out, std::string("\x34\x12\xD4\xC3\xB2\xA1\x01\x02\x03\x04\x05\x06", 12));
  EXPECT_EQ(getU16(out, 0), 0x1234);
  EXPECT_EQ(getU32(out, 2), 0xA1B2C3D4U);
  EXPECT_EQ(getLittleEndian(out, 6, 6), 0x0000'0605'0403'0201ULL);
  EXPECT_EQ(getLittleEndian(out, 7, 2), 0x0302U) << "any offset, no alignment";
}

TEST(LittleEndian, FloatsTravelAsTheirIeeeBits) {
  std::string out;
  putFloat(out, 1.0F);  // 0x3F800000
  putFloat(out, -std::numeric_limits<float>::infinity());
  EXPECT_EQ(out, std::string("\x00\x00\x80\x3F\x00\x00\x80\xFF", 8));
  EXPECT_EQ(getFloat(out, 0), 1.0F);
  EXPECT_EQ(getFloat(out, 4), -std::numeric_limits<float>::infinity());
}

}  // namespace
}  // namespace fogmap
