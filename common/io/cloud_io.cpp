#include "common/io/cloud_io.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>

namespace fogmap {
namespace {

namespace fs = std::filesystem;

// The binary formats are little-endian float32 and Point is four packed floats, so a record's
// first 16 bytes can be copied straight into a Point.
static_assert(std::endian::native == std::endian::little, "cloud_io assumes a little-endian host");
static_assert(sizeof(Point) == 4 * sizeof(float), "Point must be four packed floats");

constexpr std::size_t kKittiRecordBytes = 16;     // x y z reflectance
constexpr std::size_t kNuscenesRecordBytes = 20;  // x y z intensity ring

// `name` is the file's path, or whatever the caller named the bytes by.
Error badFile(const std::string& name, const std::string& problem) { return invalidArgument(name + ": " + problem); }

// Appends a decoded point, or counts it as non-finite and drops it unless the caller keeps them.
void addPoint(LoadedCloud& loaded, const Point& p, const ReadLimits& limits) {
  if (isFinitePoint(p)) {
    loaded.points.push_back(p);
  } else if (limits.keep_non_finite) {
    loaded.points.push_back(p);
    ++loaded.kept_non_finite;
  } else {
    ++loaded.dropped_non_finite;
  }
}

Error tooLarge(const std::string& name, std::uintmax_t size, const ReadLimits& limits) {
  return badFile(name, "the file has " + std::to_string(size) + " bytes, more than the scan size bound of " +
                           std::to_string(limits.max_bytes) + " bytes (topology max_scan_bytes)");
}

Expected<std::string> readWholeFile(const fs::path& path, const ReadLimits& limits) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found) return notFound(path.string() + ": no such file");
  if (ec) return ioError(path.string() + ": cannot access the file: " + ec.message());
  if (!fs::is_regular_file(status)) return badFile(path.string(), "not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) return ioError(path.string() + ": cannot get the file size: " + ec.message());
  if (size > limits.max_bytes) return tooLarge(path.string(), size, limits);

  std::ifstream in(path, std::ios::binary);
  if (!in) return ioError(path.string() + ": cannot open the file for reading");
  std::string bytes(static_cast<std::size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    return ioError(path.string() + ": read only " + std::to_string(in.gcount()) + " of " + std::to_string(size) +
                   " bytes");
  }
  return bytes;
}

// Headerless float32 records whose first four floats are x, y, z, intensity (KITTI, nuScenes).
Expected<LoadedCloud> parseFloatRecords(std::string_view bytes, const std::string& name, std::size_t record_bytes,
                                        const char* format_name, const ReadLimits& limits) {
  if (bytes.size() > limits.max_bytes) return tooLarge(name, bytes.size(), limits);
  if (bytes.empty()) return badFile(name, "the file is empty (0 bytes)");
  if (bytes.size() % record_bytes != 0) {
    return badFile(name, "size " + std::to_string(bytes.size()) + " bytes is not a multiple of the " +
                             std::to_string(record_bytes) + "-byte " + format_name + " point record (" +
                             std::to_string(bytes.size() % record_bytes) +
                             " bytes left over): the file is truncated or has trailing data");
  }

  const std::size_t count = bytes.size() / record_bytes;
  LoadedCloud loaded;
  loaded.points.reserve(count);
  const char* record = bytes.data();
  for (std::size_t i = 0; i < count; ++i, record += record_bytes) {
    Point p;
    std::memcpy(&p, record, sizeof(Point));
    addPoint(loaded, p, limits);
  }
  return loaded;
}

// ---- PCD --------------------------------------------------------------------------------------
// PCL's reader is lenient: it warns and carries on when the data is shorter or longer than the
// header says, and turns unparseable numbers into 0. So the header and the data size are checked
// here first, and PCL only decodes files that are known to be consistent.

struct PcdField {
  std::string name;
  std::size_t size = 4;
  char type = 'F';
  std::size_t count = 1;
};

enum class PcdData { kAscii, kBinary, kBinaryCompressed };

struct PcdHeader {
  std::vector<PcdField> fields;
  std::uint64_t points = 0;
  PcdData data = PcdData::kAscii;
  std::size_t data_offset = 0;  // first byte after the DATA line

  std::size_t valuesPerPoint() const {
    std::size_t n = 0;
    for (const PcdField& f : fields) n += f.count;
    return n;
  }
  // Bytes a point takes; `with_padding` false skips "_" fields, which binary_compressed omits.
  std::size_t pointStep(bool with_padding = true) const {
    std::size_t n = 0;
    for (const PcdField& f : fields) {
      if (with_padding || f.name != "_") n += f.size * f.count;
    }
    return n;
  }
  bool hasField(std::string_view name) const {
    return std::any_of(fields.begin(), fields.end(), [&](const PcdField& f) { return f.name == name; });
  }
};

std::vector<std::string_view> splitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t pos = 0;
  while (pos < line.size()) {
    while (pos < line.size() && (line[pos] == ' ' || line[pos] == '\t' || line[pos] == '\r')) ++pos;
    const std::size_t start = pos;
    while (pos < line.size() && line[pos] != ' ' && line[pos] != '\t' && line[pos] != '\r') ++pos;
    if (pos > start) words.push_back(line.substr(start, pos - start));
  }
  return words;
}

// A header line shown in an error message: short, and without raw binary bytes.
std::string printable(std::string_view text) {
  constexpr std::size_t kMaxChars = 40;
  std::string out;
  for (const char c : text.substr(0, kMaxChars)) {
    out += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  if (text.size() > kMaxChars) out += "...";
  return out;
}

std::optional<std::uint64_t> parseUnsigned(std::string_view word) {
  std::uint64_t value = 0;
  const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (ec != std::errc() || end != word.data() + word.size()) return std::nullopt;
  return value;
}

bool isNumber(std::string_view word) {
  if (!word.empty() && word.front() == '+') word.remove_prefix(1);  // from_chars rejects a leading '+'
  double value = 0.0;
  const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
  // Out-of-range values still are numbers; PCL stores them as inf or 0 and finiteness is checked later.
  return (ec == std::errc() || ec == std::errc::result_out_of_range) && end == word.data() + word.size();
}

bool isValidFieldType(char type, std::size_t size) {
  switch (type) {
    case 'F': return size == 4 || size == 8;
    case 'I':
    case 'U': return size == 1 || size == 2 || size == 4 || size == 8;
    default: return false;
  }
}

Expected<PcdHeader> parsePcdHeader(const std::string& name, std::string_view text) {
  const auto unparseable = [&](const std::string& why) { return badFile(name, "unparseable PCD header: " + why); };

  PcdHeader header;
  std::vector<std::string_view> names;
  std::vector<std::string_view> sizes;
  std::vector<std::string_view> types;
  std::vector<std::string_view> counts;
  std::optional<std::uint64_t> width;
  std::optional<std::uint64_t> height;
  std::optional<std::uint64_t> points;
  std::optional<std::string_view> data;
  std::vector<std::string_view> seen;  // header lines read so far (COLUMNS counts as FIELDS)

  std::size_t pos = 0;
  for (int line_number = 1; !data; ++line_number) {
    if (pos >= text.size()) return unparseable("the header ends without a DATA line");
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;

    const std::vector<std::string_view> words = splitWords(line);
    if (line.empty()) continue;
    // PCL stops reading the header at a line of only whitespace (e.g. "\r" from CRLF) and then reads
    // zero points, so such a line is rejected here rather than skipped.
    if (words.empty()) {
      return unparseable("line " + std::to_string(line_number) + " holds only whitespace (PCL would stop there)");
    }
    if (words.front().front() == '#') continue;
    const std::string_view key = words.front();
    const std::vector<std::string_view> values(words.begin() + 1, words.end());
    const auto single = [&](std::optional<std::uint64_t>& target) -> std::optional<Error> {
      if (values.size() != 1 || !(target = parseUnsigned(values.front()))) {
        return unparseable(std::string(key) + " needs one non-negative integer, got '" + printable(line) + "'");
      }
      return std::nullopt;
    };

    if (key == "VERSION") continue;
    // PCL sizes its point buffer when it reads POINTS, from the fields it has read by then, and
    // takes the last of repeated lines: a field line after POINTS would make it write past the
    // buffer. So every line comes once, and POINTS after the field lines.
    const std::string_view kind = key == "COLUMNS" ? "FIELDS" : key;
    if (std::find(seen.begin(), seen.end(), kind) != seen.end()) {
      return unparseable(std::string(kind) + " appears twice (line " + std::to_string(line_number) + ")");
    }
    seen.push_back(kind);
    if (points && (kind == "FIELDS" || kind == "SIZE" || kind == "TYPE" || kind == "COUNT")) {
      return unparseable(std::string(kind) + " comes after POINTS (the fields must come first)");
    }
    if (key == "FIELDS" || key == "COLUMNS") {
      names = values;
    } else if (key == "SIZE") {
      if (names.empty()) return unparseable("SIZE comes before FIELDS");  // PCL needs this order
      sizes = values;
    } else if (key == "TYPE") {
      if (sizes.empty()) return unparseable("TYPE comes before SIZE");
      types = values;
    } else if (key == "COUNT") {
      if (types.empty()) return unparseable("COUNT comes before TYPE");
      counts = values;
    } else if (key == "WIDTH") {
      if (auto error = single(width)) return *error;
    } else if (key == "HEIGHT") {
      if (auto error = single(height)) return *error;
    } else if (key == "POINTS") {
      if (auto error = single(points)) return *error;
    } else if (key == "VIEWPOINT") {
      if (values.size() != 7) return unparseable("VIEWPOINT needs 7 values (tx ty tz qw qx qy qz)");
    } else if (key == "DATA") {
      if (values.size() != 1) return unparseable("DATA needs one value (ascii, binary or binary_compressed)");
      data = values.front();
      header.data_offset = std::min(pos, text.size());
    } else {
      return unparseable("line " + std::to_string(line_number) + " is not a PCD header line: '" + printable(line) +
                         "'");
    }
  }

  if (*data == "ascii") {
    header.data = PcdData::kAscii;
  } else if (*data == "binary") {
    header.data = PcdData::kBinary;
  } else if (*data == "binary_compressed") {
    header.data = PcdData::kBinaryCompressed;
  } else {
    return unparseable("unknown DATA kind '" + printable(*data) + "'");
  }

  if (names.empty()) return unparseable("no FIELDS line");
  if (sizes.size() != names.size() || types.size() != names.size()) {
    return unparseable("FIELDS, SIZE and TYPE must list the same number of entries (" + std::to_string(names.size()) +
                       ", " + std::to_string(sizes.size()) + ", " + std::to_string(types.size()) + ")");
  }
  // Without a COUNT line every field holds one value; with one, it lists a count per field.
  const bool has_counts = std::find(seen.begin(), seen.end(), "COUNT") != seen.end();
  if (has_counts && counts.size() != names.size()) {
    return unparseable("COUNT lists " + std::to_string(counts.size()) + " entries for " +
                       std::to_string(names.size()) + " fields");
  }
  for (std::size_t i = 0; i < names.size(); ++i) {
    PcdField field;
    field.name = std::string(names[i]);
    const std::optional<std::uint64_t> size = parseUnsigned(sizes[i]);
    const std::optional<std::uint64_t> count = has_counts ? parseUnsigned(counts[i]) : std::optional<std::uint64_t>{1};
    if (!size || types[i].size() != 1 || !isValidFieldType(types[i].front(), *size)) {
      return unparseable("field '" + printable(names[i]) + "' has an invalid SIZE/TYPE '" + printable(sizes[i]) +
                         "'/'" + printable(types[i]) + "'");
    }
    if (!count || *count == 0 || *count > 1'000'000) {
      return unparseable("field '" + printable(names[i]) + "' has an invalid COUNT '" +
                         printable(has_counts ? counts[i] : "") + "'");
    }
    field.size = static_cast<std::size_t>(*size);
    field.type = types[i].front();
    field.count = static_cast<std::size_t>(*count);
    header.fields.push_back(std::move(field));
  }

  if (!points) return unparseable("no POINTS line");
  header.points = *points;
  if (width || height) {
    const std::uint64_t w = width.value_or(0);
    const std::uint64_t h = height.value_or(1);
    const bool overflows = h != 0 && w > std::numeric_limits<std::uint64_t>::max() / h;
    if (overflows || w * h != header.points) {
      return badFile(name, "PCD header count mismatch: WIDTH x HEIGHT = " + std::to_string(w) + " x " +
                               std::to_string(h) + " but POINTS = " + std::to_string(header.points));
    }
  }
  for (const char* axis : {"x", "y", "z"}) {
    if (!header.hasField(axis)) {
      return badFile(name, std::string("PCD file has no '") + axis + "' field (x, y and z are required)");
    }
  }
  return header;
}

// Bytes after a PCD's declared data: zero padding (an export artefact PCL ignores) is counted and
// accepted; any other byte is an error.
Expected<std::size_t> trailingZeroBytes(const std::string& name, std::string_view bytes, std::size_t data_end,
                                        std::uint64_t points) {
  const std::string_view tail = bytes.substr(data_end);
  const std::size_t non_zero = tail.find_first_not_of('\0');
  if (non_zero == std::string_view::npos) return tail.size();
  return badFile(name, "PCD file has " + std::to_string(tail.size()) + " bytes of trailing data after the " +
                           std::to_string(points) + " points the header declares, and byte " +
                           std::to_string(data_end + non_zero) + " of the file is not zero (only zero padding is accepted)");
}

// Compares the bytes from `data_start` on with the `expected` bytes the header declares; returns the
// number of trailing zero bytes.
Expected<std::size_t> checkBinaryDataSize(const std::string& name, std::string_view bytes, std::size_t data_start,
                                          std::uint64_t expected, std::uint64_t points, const char* what) {
  const std::uint64_t available = bytes.size() - data_start;
  if (available < expected) {
    return badFile(name, "PCD data is truncated: the header declares " + std::to_string(points) + " points (" +
                             std::to_string(expected) + " bytes of " + what + ") but the file holds only " +
                             std::to_string(available) + " bytes");
  }
  return trailingZeroBytes(name, bytes, data_start + static_cast<std::size_t>(expected), points);
}

// Checks the data against the header; returns the number of trailing zero bytes.
Expected<std::size_t> checkPcdData(const std::string& name, const PcdHeader& header, std::string_view bytes) {
  const std::string_view body = bytes.substr(header.data_offset);
  const std::uint64_t step = header.pointStep();
  if (header.points > std::numeric_limits<std::uint64_t>::max() / std::max<std::uint64_t>(step, 1)) {
    return badFile(name, "PCD header declares an impossible number of points (" + std::to_string(header.points) + ")");
  }

  switch (header.data) {
    case PcdData::kBinary:
      return checkBinaryDataSize(name, bytes, header.data_offset, header.points * step, header.points, "point data");

    case PcdData::kBinaryCompressed: {
      // PCL 1.13 unpacks such files into a buffer without the padding but reads them with it.
      if (header.hasField("_")) {
        return badFile(name, "binary_compressed PCD files with padding ('_') fields are not supported; "
                             "save the cloud as binary or ascii");
      }
      // Layout: uint32 compressed size, uint32 uncompressed size, LZF block.
      if (body.size() < 8) {
        return badFile(name, "PCD data is truncated: binary_compressed data needs an 8-byte size prefix but the file "
                             "holds only " + std::to_string(body.size()) + " bytes after the header");
      }
      std::uint32_t compressed = 0;
      std::uint32_t uncompressed = 0;
      std::memcpy(&compressed, body.data(), 4);
      std::memcpy(&uncompressed, body.data() + 4, 4);
      const std::uint64_t expected_uncompressed = header.points * header.pointStep(false);
      if (uncompressed != expected_uncompressed) {
        return badFile(name, "PCD header count mismatch: the header declares " + std::to_string(header.points) +
                                 " points (" + std::to_string(expected_uncompressed) +
                                 " bytes) but the compressed block unpacks to " + std::to_string(uncompressed) +
                                 " bytes");
      }
      return checkBinaryDataSize(name, bytes, header.data_offset + 8, compressed, header.points, "compressed data");
    }

    case PcdData::kAscii: {
      // Zero padding after the last line is accepted as after binary data (PCL stops at POINTS lines).
      const std::size_t last = bytes.find_last_not_of('\0');
      const std::size_t data_end =
          last == std::string_view::npos ? header.data_offset : std::max(header.data_offset, last + 1);
      const std::string_view lines_text = bytes.substr(header.data_offset, data_end - header.data_offset);
      const std::size_t values_per_point = header.valuesPerPoint();
      std::uint64_t lines = 0;
      std::size_t pos = 0;
      while (pos < lines_text.size()) {
        std::size_t end = lines_text.find('\n', pos);
        if (end == std::string_view::npos) end = lines_text.size();
        const std::vector<std::string_view> words = splitWords(lines_text.substr(pos, end - pos));
        pos = end + 1;
        if (words.empty()) continue;
        ++lines;
        if (words.size() != values_per_point) {
          return badFile(name, "PCD data line " + std::to_string(lines) + " has " + std::to_string(words.size()) +
                                   " values, expected " + std::to_string(values_per_point));
        }
        for (const std::string_view word : words) {
          if (!isNumber(word)) {
            return badFile(name, "PCD data line " + std::to_string(lines) + " has a value that is not a number: '" +
                                     printable(word) + "'");
          }
        }
      }
      if (lines != header.points) {
        return badFile(name, "PCD header count mismatch: POINTS says " + std::to_string(header.points) +
                                 " but the data has " + std::to_string(lines) + " points");
      }
      return bytes.size() - data_end;
    }
  }
  return Error{ErrorCode::kInternal, name + ": unhandled PCD data kind"};
}

float fieldValue(const std::uint8_t* at, std::uint8_t datatype) {
  const auto as = [at]<class T>(T) {
    T value;
    std::memcpy(&value, at, sizeof(T));
    return static_cast<float>(value);
  };
  switch (datatype) {
    case pcl::PCLPointField::INT8: return as(std::int8_t{});
    case pcl::PCLPointField::UINT8: return as(std::uint8_t{});
    case pcl::PCLPointField::INT16: return as(std::int16_t{});
    case pcl::PCLPointField::UINT16: return as(std::uint16_t{});
    case pcl::PCLPointField::INT32: return as(std::int32_t{});
    case pcl::PCLPointField::UINT32: return as(std::uint32_t{});
    case pcl::PCLPointField::INT64: return as(std::int64_t{});
    case pcl::PCLPointField::UINT64: return as(std::uint64_t{});
    case pcl::PCLPointField::FLOAT32: return as(float{});
    case pcl::PCLPointField::FLOAT64: return as(double{});
    default: return std::numeric_limits<float>::quiet_NaN();  // unknown type: the point is dropped
  }
}

// PCL's datatype for a field fogmap's header check accepted (isValidFieldType).
std::uint8_t pclDatatype(const PcdField& field) {
  switch (field.type) {
    case 'F': return field.size == 4 ? pcl::PCLPointField::FLOAT32 : pcl::PCLPointField::FLOAT64;
    case 'I':
      return field.size == 1 ? pcl::PCLPointField::INT8
             : field.size == 2 ? pcl::PCLPointField::INT16
             : field.size == 4 ? pcl::PCLPointField::INT32
                               : pcl::PCLPointField::INT64;
    default:
      return field.size == 1 ? pcl::PCLPointField::UINT8
             : field.size == 2 ? pcl::PCLPointField::UINT16
             : field.size == 4 ? pcl::PCLPointField::UINT32
                               : pcl::PCLPointField::UINT64;
  }
}

// PCL fills the buffer it sized from its own reading of the header: it may decode only when that
// reading is fogmap's (fields, their layout, the point count), or it could write past the buffer.
bool sameLayout(const PcdHeader& header, const pcl::PCLPointCloud2& cloud) {
  if (cloud.fields.size() != header.fields.size() || cloud.point_step != header.pointStep()) return false;
  std::size_t offset = 0;
  for (std::size_t i = 0; i < header.fields.size(); ++i) {
    const PcdField& field = header.fields[i];
    const pcl::PCLPointField& decoded = cloud.fields[i];
    if (decoded.name != field.name || decoded.offset != offset || decoded.count != field.count ||
        decoded.datatype != pclDatatype(field)) {
      return false;
    }
    offset += field.size * field.count;
  }
  return std::uint64_t{cloud.width} * cloud.height == header.points &&
         cloud.data.size() == header.points * header.pointStep();
}

const pcl::PCLPointField* findField(const pcl::PCLPointCloud2& cloud, std::string_view name) {
  for (const pcl::PCLPointField& f : cloud.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

}  // namespace

Expected<CloudFormat> cloudFormatFromPath(const fs::path& path) {
  std::string name = path.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
  if (name.ends_with(".pcd.bin")) return CloudFormat::kNuscenesBin;
  if (name.ends_with(".bin")) return CloudFormat::kKittiBin;
  if (name.ends_with(".pcd")) return CloudFormat::kPcd;
  return badFile(path.string(), "unknown point cloud format (expected a .bin, .pcd.bin or .pcd file name)");
}

Expected<LoadedCloud> parseKittiBin(std::string_view bytes, const std::string& name, const ReadLimits& limits) {
  return parseFloatRecords(bytes, name, kKittiRecordBytes, "KITTI", limits);
}

Expected<LoadedCloud> parseNuscenesBin(std::string_view bytes, const std::string& name, const ReadLimits& limits) {
  return parseFloatRecords(bytes, name, kNuscenesRecordBytes, "nuScenes", limits);
}

Expected<LoadedCloud> parsePcd(std::string_view bytes, const std::string& name, const ReadLimits& limits) {
  if (bytes.size() > limits.max_bytes) return tooLarge(name, bytes.size(), limits);
  if (bytes.empty()) return badFile(name, "the file is empty (0 bytes)");

  Expected<PcdHeader> header = parsePcdHeader(name, bytes);
  if (!header) return header.error();
  const Expected<std::size_t> trailing_zero_bytes = checkPcdData(name, *header, bytes);
  if (!trailing_zero_bytes) return trailing_zero_bytes.error();
  LoadedCloud loaded;
  loaded.trailing_zero_bytes = *trailing_zero_bytes;
  if (header->points == 0) return loaded;

  // PCL decodes what the checks above accepted, from these same bytes (a file is read once). It
  // gets the header alone first, so it cannot take data for header lines.
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);  // the checks above report every problem we know
  pcl::PCLPointCloud2 cloud;
  int result = -1;
  try {
    pcl::PCDReader reader;
    Eigen::Vector4f origin;
    Eigen::Quaternionf orientation;
    int version = 0;
    int data_type = 0;
    unsigned int data_idx = 0;
    std::istringstream header_text(std::string(bytes.substr(0, header->data_offset)), std::ios::binary);
    result = reader.readHeader(header_text, cloud, origin, orientation, version, data_type, data_idx);
    const int expected_type = header->data == PcdData::kAscii ? 0 : header->data == PcdData::kBinary ? 1 : 2;
    if (result >= 0 && (data_idx != header->data_offset || data_type != expected_type || !sameLayout(*header, cloud))) {
      return badFile(name, "PCL read the PCD header differently from fogmap");
    }
    if (result >= 0 && data_type == 0) {
      std::istringstream body(std::string(bytes.substr(data_idx)));
      result = reader.readBodyASCII(body, cloud, version);
    } else if (result >= 0) {
      // Within the bytes: checkPcdData measured the data against the layout PCL now shares.
      result = reader.readBodyBinary(reinterpret_cast<const unsigned char*>(bytes.data()), cloud, version,
                                     data_type == 2, data_idx);
    }
  } catch (const std::exception& e) {
    return badFile(name, std::string("PCL could not read the PCD file: ") + e.what());
  } catch (...) {
    return badFile(name, "PCL could not read the PCD file");
  }
  if (result < 0 && header->data == PcdData::kBinaryCompressed) {
    return badFile(name, "the binary_compressed data does not decompress (a corrupt LZF block)");
  }
  if (result < 0) return badFile(name, "PCL could not read the PCD file");

  const std::size_t count = static_cast<std::size_t>(cloud.width) * cloud.height;
  const pcl::PCLPointField* x = findField(cloud, "x");
  const pcl::PCLPointField* y = findField(cloud, "y");
  const pcl::PCLPointField* z = findField(cloud, "z");
  const pcl::PCLPointField* intensity = findField(cloud, "intensity");
  if (count != header->points || cloud.data.size() < count * cloud.point_step || !x || !y || !z) {
    return badFile(name, "PCL decoded the PCD file differently from its header");
  }

  loaded.points.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint8_t* base = cloud.data.data() + i * cloud.point_step;
    Point p;
    p.x = fieldValue(base + x->offset, x->datatype);
    p.y = fieldValue(base + y->offset, y->datatype);
    p.z = fieldValue(base + z->offset, z->datatype);
    if (intensity) p.intensity = fieldValue(base + intensity->offset, intensity->datatype);
    addPoint(loaded, p, limits);
  }
  return loaded;
}

Expected<LoadedCloud> readKittiBin(const fs::path& path, const ReadLimits& limits) {
  const Expected<std::string> bytes = readWholeFile(path, limits);
  if (!bytes) return bytes.error();
  return parseKittiBin(*bytes, path.string(), limits);
}

Expected<LoadedCloud> readNuscenesBin(const fs::path& path, const ReadLimits& limits) {
  const Expected<std::string> bytes = readWholeFile(path, limits);
  if (!bytes) return bytes.error();
  return parseNuscenesBin(*bytes, path.string(), limits);
}

Expected<LoadedCloud> readPcd(const fs::path& path, const ReadLimits& limits) {
  const Expected<std::string> bytes = readWholeFile(path, limits);
  if (!bytes) return bytes.error();
  return parsePcd(*bytes, path.string(), limits);
}

Expected<LoadedCloud> readCloud(const fs::path& path, const ReadLimits& limits) {
  const Expected<CloudFormat> format = cloudFormatFromPath(path);
  if (!format) return format.error();
  switch (*format) {
    case CloudFormat::kKittiBin: return readKittiBin(path, limits);
    case CloudFormat::kNuscenesBin: return readNuscenesBin(path, limits);
    case CloudFormat::kPcd: return readPcd(path, limits);
  }
  return Error{ErrorCode::kInternal, path.string() + ": unhandled cloud format"};
}

namespace {

Status writeFile(const fs::path& path, std::string_view header, const Cloud& cloud) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return ioError(path.string() + ": cannot open the file for writing");
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  out.write(reinterpret_cast<const char*>(cloud.data()), static_cast<std::streamsize>(cloud.size() * sizeof(Point)));
  out.close();
  if (!out) return ioError(path.string() + ": writing the file failed");
  return {};
}

}  // namespace

Status writeKittiBin(const fs::path& path, const Cloud& cloud) { return writeFile(path, {}, cloud); }

Status writePcd(const fs::path& path, const Cloud& cloud) {
  // Point's memory layout is exactly "x y z intensity" as four float32, so the body is a plain copy.
  const std::string n = std::to_string(cloud.size());
  const std::string header =
      "# .PCD v0.7 - Point Cloud Data file format\n"
      "VERSION 0.7\n"
      "FIELDS x y z intensity\n"
      "SIZE 4 4 4 4\n"
      "TYPE F F F F\n"
      "COUNT 1 1 1 1\n"
      "WIDTH " + n + "\n"
      "HEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\n"
      "POINTS " + n + "\n"
      "DATA binary\n";
  return writeFile(path, header, cloud);
}

}  // namespace fogmap
