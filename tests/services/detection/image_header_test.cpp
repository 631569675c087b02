// Image headers read without decoding, against OpenCV's own encoders as the oracle: every format
// a frame source decodes gives back the size it was written with.
#include "services/detection/image_header.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace fogmap {
namespace {

std::vector<std::uint8_t> encoded(const std::string& extension, int width, int height, int type = CV_8UC3) {
  std::vector<std::uint8_t> bytes;
  cv::imencode(extension, cv::Mat(height, width, type, cv::Scalar::all(90)), bytes);
  return bytes;
}

std::vector<std::uint8_t> bytesOf(const std::string& text) { return {text.begin(), text.end()}; }

TEST(ImageHeader, GivesTheSizeEveryDecodedFormatWasWrittenWith) {
  struct Case {
    std::string extension;
    ImageFormat format;
    int type;
  };
  const std::vector<Case> cases{{".png", ImageFormat::kPng, CV_8UC3},  {".png", ImageFormat::kPng, CV_16UC1},
                                {".jpg", ImageFormat::kJpeg, CV_8UC3}, {".jpg", ImageFormat::kJpeg, CV_8UC1},
                                {".bmp", ImageFormat::kBmp, CV_8UC3},  {".ppm", ImageFormat::kPnm, CV_8UC3},
                                {".pgm", ImageFormat::kPnm, CV_8UC1},  {".pam", ImageFormat::kPnm, CV_8UC3}};
  for (const Case& c : cases) {
    for (const cv::Size size : {cv::Size(1, 1), cv::Size(1242, 375), cv::Size(37, 300)}) {
      SCOPED_TRACE(c.extension + " " + std::to_string(size.width) + " x " + std::to_string(size.height));
      const std::vector<std::uint8_t> bytes = encoded(c.extension, size.width, size.height, c.type);
      ASSERT_FALSE(bytes.empty());
      EXPECT_EQ(imageFormatOf(bytes), c.format);
      const Expected<ImageHeader> header = readImageHeader(bytes);
      ASSERT_TRUE(header.ok()) << header.error().message;
      EXPECT_EQ(header->format, c.format);
      EXPECT_EQ(header->width, static_cast<std::uint32_t>(size.width));
      EXPECT_EQ(header->height, static_cast<std::uint32_t>(size.height));
      EXPECT_EQ(header->pixels(), static_cast<std::uint64_t>(size.area()));
    }
  }
}

TEST(ImageHeader, FindsAJpegFrameHeaderBehindMetadataSegments) {
  std::vector<std::uint8_t> jpeg = encoded(".jpg", 640, 480);
  // A 60 kB APP1 segment (as EXIF with a thumbnail) and a comment right after SOI.
  std::vector<std::uint8_t> extra{0xFF, 0xE1, 0xEA, 0x62};
  extra.resize(extra.size() + 0xEA62 - 2, 0x45);
  const std::string comment = "a comment";
  extra.insert(extra.end(), {0xFF, 0xFE, 0x00, static_cast<std::uint8_t>(comment.size() + 2)});
  extra.insert(extra.end(), comment.begin(), comment.end());
  jpeg.insert(jpeg.begin() + 2, extra.begin(), extra.end());
  const Expected<ImageHeader> header = readImageHeader(jpeg);
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_EQ(header->width, 640u);
  EXPECT_EQ(header->height, 480u);
  // OpenCV agrees: the bytes are still a JPEG of that size.
  EXPECT_EQ(cv::imdecode(jpeg, cv::IMREAD_COLOR).size(), cv::Size(640, 480));
}

TEST(ImageHeader, ReadsTheSizeOfAHugeImageFromTheFirstBytesAlone) {
  // PNG: signature and IHDR only, 20,000 x 20,000; nothing after it is read.
  std::vector<std::uint8_t> png = encoded(".png", 4, 4);
  png.resize(33);
  const std::uint8_t huge[] = {0x00, 0x00, 0x4E, 0x20};  // 20000
  std::copy(std::begin(huge), std::end(huge), png.begin() + 16);
  std::copy(std::begin(huge), std::end(huge), png.begin() + 20);
  const Expected<ImageHeader> header = readImageHeader(png);
  ASSERT_TRUE(header.ok()) << header.error().message;
  EXPECT_EQ(header->pixels(), 400'000'000u);
  // A BMP stored top-down has a negative height.
  std::vector<std::uint8_t> bmp = encoded(".bmp", 3, 5);
  const std::int32_t top_down = -5;
  std::memcpy(bmp.data() + 22, &top_down, 4);
  const Expected<ImageHeader> bmp_header = readImageHeader(bmp);
  ASSERT_TRUE(bmp_header.ok()) << bmp_header.error().message;
  EXPECT_EQ(bmp_header->height, 5u);
}

TEST(ImageHeader, AnUnknownFormatIsNamedAsSuch) {
  for (const std::string text : {"", "this is not an image", "GIF89a....", "P9 1 1\n"}) {
    SCOPED_TRACE("'" + text + "'");
    EXPECT_FALSE(imageFormatOf(bytesOf(text)).has_value());
    const Expected<ImageHeader> header = readImageHeader(bytesOf(text));
    ASSERT_FALSE(header.ok());
    EXPECT_NE(header.error().message.find("unknown format"), std::string::npos) << header.error().message;
  }
}

TEST(ImageHeader, AHeaderCutShortOrWithoutASizeIsAnErrorNamingTheFormat) {
  std::vector<std::vector<std::uint8_t>> bad;
  std::vector<std::uint8_t> png = encoded(".png", 8, 8);
  bad.emplace_back(png.begin(), png.begin() + 20);  // cut inside IHDR
  std::vector<std::uint8_t> zero_width = png;
  zero_width[16] = zero_width[17] = zero_width[18] = zero_width[19] = 0;
  bad.push_back(zero_width);
  std::vector<std::uint8_t> jpeg = encoded(".jpg", 8, 8);
  bad.emplace_back(jpeg.begin(), jpeg.begin() + 30);  // cut before SOF
  bad.push_back({0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x08});  // a scan before any frame header
  bad.push_back({0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x01});  // a segment length below 2
  std::vector<std::uint8_t> bmp = encoded(".bmp", 8, 8);
  bad.emplace_back(bmp.begin(), bmp.begin() + 20);
  bad.push_back(bytesOf("P6\n# only a comment\n"));
  bad.push_back(bytesOf("P6 12\n"));
  bad.push_back(bytesOf("P5 123456789012 4\n255\n"));
  bad.push_back(bytesOf("P7\nDEPTH 3\nENDHDR\n"));
  for (std::size_t i = 0; i < bad.size(); ++i) {
    SCOPED_TRACE("case " + std::to_string(i));
    ASSERT_TRUE(imageFormatOf(bad[i]).has_value());
    const Expected<ImageHeader> header = readImageHeader(bad[i]);
    ASSERT_FALSE(header.ok());
    EXPECT_NE(header.error().message.find(std::string(imageFormatName(*imageFormatOf(bad[i]))) + " header"),
              std::string::npos)
        << header.error().message;
  }
}

}  // namespace
}  // namespace fogmap
