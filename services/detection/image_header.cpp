#include "services/detection/image_header.hpp"

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <iterator>
#include <string>
#include <string_view>

namespace fogmap {
namespace {

// PNG and PNM cap sizes at 2^31 - 1 (and so do the decoders' int sizes).
constexpr std::uint64_t kMaxSide = 0x7fffffffU;

using Bytes = std::span<const std::uint8_t>;

std::uint32_t be16(Bytes b, std::size_t at) { return (std::uint32_t{b[at]} << 8) | b[at + 1]; }
std::uint32_t be32(Bytes b, std::size_t at) { return (be16(b, at) << 16) | be16(b, at + 2); }
std::uint32_t le16(Bytes b, std::size_t at) { return std::uint32_t{b[at]} | (std::uint32_t{b[at + 1]} << 8); }
std::uint32_t le32(Bytes b, std::size_t at) { return le16(b, at) | (le16(b, at + 2) << 16); }

Error bad(ImageFormat format, const std::string& what) {
  return invalidArgument(std::string(imageFormatName(format)) + " header: " + what);
}

Expected<ImageHeader> sized(ImageFormat format, std::uint64_t width, std::uint64_t height) {
  if (width == 0 || height == 0) {
    return bad(format, "gives a size of " + std::to_string(width) + " x " + std::to_string(height));
  }
  if (width > kMaxSide || height > kMaxSide) {
    return bad(format, "gives a side above 2^31 - 1 (" + std::to_string(width) + " x " + std::to_string(height) + ")");
  }
  return ImageHeader{format, static_cast<std::uint32_t>(width), static_cast<std::uint32_t>(height)};
}

Expected<ImageHeader> readPng(Bytes b) {
  // Signature (8), then the first chunk: length (4), type (4), and IHDR's width and height.
  if (b.size() < 24) return bad(ImageFormat::kPng, "the file ends before IHDR");
  if (std::string_view(reinterpret_cast<const char*>(b.data() + 12), 4) != "IHDR" || be32(b, 8) != 13) {
    return bad(ImageFormat::kPng, "the first chunk is not a 13-byte IHDR");
  }
  return sized(ImageFormat::kPng, be32(b, 16), be32(b, 20));
}

std::string markerName(std::uint8_t marker) {
  constexpr char kHex[] = "0123456789ABCDEF";
  return std::string("0xFF") + kHex[marker >> 4] + kHex[marker & 15];
}

bool isJpegFrameHeader(std::uint8_t marker) {
  // SOF0..SOF15 are C0..CF except DHT (C4), JPG (C8) and DAC (CC).
  return marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
}

Expected<ImageHeader> readJpeg(Bytes b) {
  // Segments after SOI until the first frame header: the decoder takes its size from that one
  // (a second one is an error to it). A scan or the end before it leaves no size to check.
  std::size_t at = 2;
  for (;;) {
    if (at >= b.size()) return bad(ImageFormat::kJpeg, "the file ends before a frame header (SOFn)");
    if (b[at] != 0xFF) return bad(ImageFormat::kJpeg, "no marker at byte " + std::to_string(at));
    while (at < b.size() && b[at] == 0xFF) ++at;  // fill bytes
    if (at >= b.size()) return bad(ImageFormat::kJpeg, "the file ends before a frame header (SOFn)");
    const std::uint8_t marker = b[at++];
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;  // no length
    if (marker == 0xD8 || marker == 0xD9 || marker == 0xDA || marker == 0x00) {
      return bad(ImageFormat::kJpeg, "no frame header (SOFn) before marker " + markerName(marker));
    }
    if (at + 2 > b.size()) return bad(ImageFormat::kJpeg, "the file ends inside a segment length");
    const std::uint32_t length = be16(b, at);
    if (length < 2) return bad(ImageFormat::kJpeg, "a segment length of " + std::to_string(length));
    if (isJpegFrameHeader(marker)) {
      // length (2), precision (1), height (2), width (2), components (1)
      if (length < 8 || at + 8 > b.size()) return bad(ImageFormat::kJpeg, "the frame header is cut short");
      return sized(ImageFormat::kJpeg, be16(b, at + 5), be16(b, at + 3));
    }
    at += length;
  }
}

Expected<ImageHeader> readBmp(Bytes b) {
  // File header (14), then the DIB header's size and the size fields of its kind.
  if (b.size() < 26) return bad(ImageFormat::kBmp, "the file ends inside the headers");
  const std::uint32_t dib = le32(b, 14);
  if (dib == 12) return sized(ImageFormat::kBmp, le16(b, 18), le16(b, 20));  // OS/2 BITMAPCOREHEADER
  if (dib < 40 || dib > 4096) return bad(ImageFormat::kBmp, "a DIB header of " + std::to_string(dib) + " bytes");
  const auto width = static_cast<std::int32_t>(le32(b, 18));
  const auto height = static_cast<std::int32_t>(le32(b, 22));  // negative: stored top-down
  if (width < 0) return bad(ImageFormat::kBmp, "a negative width " + std::to_string(width));
  const std::int64_t rows = height < 0 ? -static_cast<std::int64_t>(height) : height;
  return sized(ImageFormat::kBmp, static_cast<std::uint64_t>(width), static_cast<std::uint64_t>(rows));
}

// PNM header tokens: whitespace and # comments (to the end of the line) between them.
class PnmTokens {
 public:
  PnmTokens(Bytes b, std::size_t at) : b_(b), at_(at) {}
  // The next decimal number; nullopt when there is none, or it has more than 10 digits.
  std::optional<std::uint64_t> number() {
    skipBlanks();
    std::uint64_t value = 0;
    std::size_t digits = 0;
    while (at_ < b_.size() && std::isdigit(b_[at_]) != 0) {
      if (++digits > 10) return std::nullopt;
      value = value * 10 + (b_[at_++] - '0');
    }
    if (digits == 0) return std::nullopt;
    return value;
  }
  // The next word (letters, digits, underscores); empty at the end.
  std::string word() {
    skipBlanks();
    std::string w;
    while (at_ < b_.size() && w.size() < 32 && (std::isalnum(b_[at_]) != 0 || b_[at_] == '_')) w += static_cast<char>(b_[at_++]);
    return w;
  }

 private:
  void skipBlanks() {
    while (at_ < b_.size()) {
      if (b_[at_] == '#') {
        while (at_ < b_.size() && b_[at_] != '\n' && b_[at_] != '\r') ++at_;
      } else if (std::isspace(b_[at_]) != 0) {
        ++at_;
      } else {
        return;
      }
    }
  }
  Bytes b_;
  std::size_t at_;
};

Expected<ImageHeader> readPnm(Bytes b) {
  PnmTokens tokens(b, 2);
  if (b[1] != '7') {
    const auto width = tokens.number();
    const auto height = tokens.number();
    if (!width || !height) return bad(ImageFormat::kPnm, "no width and height after P" + std::string(1, static_cast<char>(b[1])));
    return sized(ImageFormat::kPnm, *width, *height);
  }
  // PAM: "WIDTH w", "HEIGHT h" and other fields in any order until ENDHDR.
  std::optional<std::uint64_t> width, height;
  for (int fields = 0; fields < 64; ++fields) {
    const std::string key = tokens.word();
    if (key.empty()) break;
    if (key == "ENDHDR") {
      if (!width || !height) break;
      return sized(ImageFormat::kPnm, *width, *height);
    }
    if (key == "WIDTH" || key == "HEIGHT") {
      const auto value = tokens.number();
      if (!value) return bad(ImageFormat::kPnm, key + " without a number");
      (key == "WIDTH" ? width : height) = value;
    }
  }
  return bad(ImageFormat::kPnm, "no WIDTH and HEIGHT before ENDHDR");
}

}  // namespace

const char* imageFormatName(ImageFormat format) {
  switch (format) {
    case ImageFormat::kPng: return "PNG";
    case ImageFormat::kJpeg: return "JPEG";
    case ImageFormat::kBmp: return "BMP";
    case ImageFormat::kPnm: return "PNM";
  }
  return "unknown";
}

std::optional<ImageFormat> imageFormatOf(Bytes b) {
  static constexpr std::uint8_t kPng[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (b.size() >= sizeof kPng && std::equal(std::begin(kPng), std::end(kPng), b.begin())) return ImageFormat::kPng;
  if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return ImageFormat::kJpeg;
  if (b.size() >= 2 && b[0] == 'B' && b[1] == 'M') return ImageFormat::kBmp;
  if (b.size() >= 3 && b[0] == 'P' && b[1] >= '1' && b[1] <= '7' && std::isspace(b[2]) != 0) return ImageFormat::kPnm;
  return std::nullopt;
}

Expected<ImageHeader> readImageHeader(Bytes bytes) {
  const std::optional<ImageFormat> format = imageFormatOf(bytes);
  if (!format) return invalidArgument("not a PNG, JPEG, BMP or PNM image (unknown format)");
  switch (*format) {
    case ImageFormat::kPng: return readPng(bytes);
    case ImageFormat::kJpeg: return readJpeg(bytes);
    case ImageFormat::kBmp: return readBmp(bytes);
    case ImageFormat::kPnm: return readPnm(bytes);
  }
  return invalidArgument("unknown image format");
}

}  // namespace fogmap
