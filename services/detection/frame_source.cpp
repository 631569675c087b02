#include "services/detection/frame_source.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <system_error>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "services/detection/image_header.hpp"
#include "common/config/camera_node.hpp"

namespace fogmap {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;
// A device that fails this many grabs in a row is taken for gone (unplugged, taken by another
// process): better to end than to spin on it.
constexpr int kMaxConsecutiveGrabFailures = 50;

std::int64_t periodNs(double rate_hz) { return std::llround(1e9 / rate_hz); }

Status checkReplay(const ReplayConfig& replay, const std::string& what) {
  if (!(replay.rate_hz > 0.0) || !std::isfinite(replay.rate_hz)) {
    return invalidArgument(what + ": rate_hz must be positive and finite");
  }
  if (replay.max_pixels == 0) return invalidArgument(what + ": max_pixels must be at least 1");
  return {};
}

bool isImageFile(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

// Days from 1970-01-01 to a proleptic Gregorian date (the civil-from-days inverse).
std::int64_t daysFromCivil(std::int64_t year, unsigned month, unsigned day) {
  year -= month <= 2 ? 1 : 0;
  const std::int64_t era = (year >= 0 ? year : year - 399) / 400;
  const auto year_of_era = static_cast<unsigned>(year - era * 400);
  const unsigned day_of_year = (153 * (month + (month > 2 ? -3 : 9)) + 2) / 5 + day - 1;
  const unsigned day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
  return era * 146097 + static_cast<std::int64_t>(day_of_era) - 719468;
}

SourceFrame done() { return {}; }

SourceFrame unreadable(std::string origin, FrameFailure failure, std::string problem) {
  SourceFrame f;
  f.outcome = FrameOutcome::kUnreadable;
  f.origin = std::move(origin);
  f.failure = failure;
  f.problem = std::move(problem);
  return f;
}

// The most bytes an image file of `max_pixels` can take: 8 bytes a pixel (a 16-bit RGBA PNG stored
// without compression, the largest of the formats read) and 1 MiB of metadata. A larger file is
// refused before it is read into memory.
std::uint64_t maxFileBytes(std::uint64_t max_pixels) {
  constexpr std::uint64_t kMetadataBytes = 1ULL << 20;
  constexpr std::uint64_t kMaxBytesPerPixel = 8;
  if (max_pixels > (UINT64_MAX - kMetadataBytes) / kMaxBytesPerPixel) return UINT64_MAX;
  return max_pixels * kMaxBytesPerPixel + kMetadataBytes;
}

std::string sizeText(std::uint64_t width, std::uint64_t height) {
  return std::to_string(width) + " x " + std::to_string(height) + " (" + std::to_string(width * height) + " pixels)";
}

// A video's or device's frames by the size the capture reports (0 x 0 when it reports none): a
// too-large refusal naming the source and the sizes, or nothing.
std::optional<SourceFrame> refuseLargeCapture(cv::VideoCapture& capture, const std::string& origin,
                                              std::uint64_t max_pixels) {
  const double width = capture.get(cv::CAP_PROP_FRAME_WIDTH);
  const double height = capture.get(cv::CAP_PROP_FRAME_HEIGHT);
  if (!(width > 0.0 && height > 0.0 && std::isfinite(width * height))) return std::nullopt;
  if (width * height <= static_cast<double>(max_pixels)) return std::nullopt;
  return unreadable(origin, FrameFailure::kTooLarge,
                    origin + ": frames of " + sizeText(static_cast<std::uint64_t>(width), static_cast<std::uint64_t>(height)) +
                        ", above the camera's max_image_pixels of " + std::to_string(max_pixels) + "; not read");
}

// A frame as read, refused when its pixels are above the limit after all (a stream that changed size).
std::optional<SourceFrame> refuseLargeFrame(const cv::Mat& image, const std::string& origin, std::uint64_t max_pixels) {
  if (static_cast<std::uint64_t>(image.total()) <= max_pixels) return std::nullopt;
  return unreadable(origin, FrameFailure::kTooLarge,
                    origin + ": a frame of " + sizeText(static_cast<std::uint64_t>(image.cols), static_cast<std::uint64_t>(image.rows)) +
                        ", above the camera's max_image_pixels of " + std::to_string(max_pixels));
}

class ImageDirectorySource final : public FrameSource {
 public:
  ImageDirectorySource(std::filesystem::path directory, std::vector<std::filesystem::path> images,
                       std::vector<std::int64_t> offsets_ns, std::int64_t pass_ns, std::string timing,
                       ReplayConfig replay)
      : directory_(std::move(directory)),
        images_(std::move(images)),
        offsets_ns_(std::move(offsets_ns)),
        pass_ns_(pass_ns),
        timing_(std::move(timing)),
        replay_(std::move(replay)) {}

  SourceFrame next() override {
    if (replay_.frames && read_ >= *replay_.frames) return done();
    const std::uint64_t index = read_ % images_.size();
    const std::uint64_t pass = read_ / images_.size();
    if (index == 0 && pass > 0) {
      // A pass in which no image could be read would make an endless loop of errors.
      if (!replay_.loop || readable_in_pass_ == 0) return done();
      readable_in_pass_ = 0;
    }
    ++read_;
    SourceFrame f = readImageFile(images_[index], replay_.max_pixels);
    if (f.outcome != FrameOutcome::kFrame) return f;
    ++readable_in_pass_;
    f.due_ns = static_cast<std::int64_t>(pass) * pass_ns_ + offsets_ns_[index];
    return f;
  }

  std::string describe() const override {
    std::ostringstream out;
    out << images_.size() << " image(s) of " << directory_.string() << " " << timing_
        << (replay_.loop ? ", looping" : "");
    if (replay_.frames) out << ", " << *replay_.frames << " frame(s)";
    return out.str();
  }

 private:
  std::filesystem::path directory_;
  std::vector<std::filesystem::path> images_;
  std::vector<std::int64_t> offsets_ns_;  // of each image after the first
  std::int64_t pass_ns_;                  // from the first image of one pass to the next pass's
  std::string timing_;
  ReplayConfig replay_;
  std::uint64_t read_ = 0;
  std::uint64_t readable_in_pass_ = 0;
};

class VideoFileSource final : public FrameSource {
 public:
  VideoFileSource(std::filesystem::path file, cv::VideoCapture capture, double fps, ReplayConfig replay)
      : file_(std::move(file)), capture_(std::move(capture)), fps_(fps), period_ns_(periodNs(fps)),
        replay_(std::move(replay)) {}

  SourceFrame next() override {
    if (finished_ || (replay_.frames && read_ >= *replay_.frames)) return done();
    if (read_ == 0) {
      // Every frame of the file has this size: refused once, unread, and the source is done.
      if (std::optional<SourceFrame> refused = refuseLargeCapture(capture_, file_.string(), replay_.max_pixels)) {
        finished_ = true;
        ++read_;
        return std::move(*refused);
      }
    }
    cv::Mat image;
    if (!capture_.read(image)) {
      // The end of the file: start again when looping, unless the pass gave nothing.
      if (!replay_.loop || in_pass_ == 0 || !capture_.set(cv::CAP_PROP_POS_FRAMES, 0) || !capture_.read(image)) {
        finished_ = true;
        return done();
      }
      pass_start_ns_ += static_cast<std::int64_t>(in_pass_) * period_ns_;
      in_pass_ = 0;
    }
    ++read_;
    const std::int64_t due = pass_start_ns_ + static_cast<std::int64_t>(in_pass_++) * period_ns_;
    const std::string origin = file_.string() + " frame " + std::to_string(in_pass_ - 1);
    if (image.type() != CV_8UC3) return unreadable(origin, FrameFailure::kNotColour, origin + ": not an 8-bit colour frame");
    if (std::optional<SourceFrame> refused = refuseLargeFrame(image, origin, replay_.max_pixels)) return std::move(*refused);
    SourceFrame f;
    f.outcome = FrameOutcome::kFrame;
    f.image_bgr = std::move(image);
    f.due_ns = due;
    f.origin = origin;
    return f;
  }

  std::string describe() const override {
    std::ostringstream out;
    out << "video " << file_.string() << " at " << fps_ << " Hz" << (replay_.loop ? ", looping" : "");
    return out.str();
  }

 private:
  std::filesystem::path file_;
  cv::VideoCapture capture_;
  double fps_;
  std::int64_t period_ns_;
  ReplayConfig replay_;
  std::uint64_t read_ = 0;
  std::uint64_t in_pass_ = 0;
  std::int64_t pass_start_ns_ = 0;
  bool finished_ = false;
};

class VideoDeviceSource final : public FrameSource {
 public:
  VideoDeviceSource(std::filesystem::path device, cv::VideoCapture capture, ReplayConfig replay, NowNs now)
      : device_(std::move(device)), capture_(std::move(capture)), replay_(std::move(replay)), now_(std::move(now)) {}

  SourceFrame next() override {
    if (failures_ >= kMaxConsecutiveGrabFailures || (replay_.frames && read_ >= *replay_.frames)) return done();
    ++read_;
    const std::string origin = device_.string() + " frame " + std::to_string(read_ - 1);
    if (read_ == 1) {
      // The device's mode does not change by itself: refused once, unread, and the source is done.
      if (std::optional<SourceFrame> refused = refuseLargeCapture(capture_, device_.string(), replay_.max_pixels)) {
        failures_ = kMaxConsecutiveGrabFailures;
        return std::move(*refused);
      }
    }
    cv::Mat image;
    const bool grabbed = capture_.read(image);
    const std::int64_t captured = now_();
    if (!grabbed || image.empty()) {
      ++failures_;
      return unreadable(origin, FrameFailure::kGrabFailed,
                        device_.string() + ": grabbing a frame failed (" + std::to_string(failures_) + " in a row)");
    }
    failures_ = 0;
    if (image.type() != CV_8UC3) return unreadable(origin, FrameFailure::kNotColour, origin + ": not an 8-bit colour frame");
    if (std::optional<SourceFrame> refused = refuseLargeFrame(image, origin, replay_.max_pixels)) return std::move(*refused);
    SourceFrame f;
    f.outcome = FrameOutcome::kFrame;
    f.image_bgr = std::move(image);
    f.capture_time_ns = captured;
    f.origin = origin;
    return f;
  }

  std::string describe() const override { return "V4L2 device " + device_.string() + " (live)"; }

 private:
  std::filesystem::path device_;
  cv::VideoCapture capture_;
  ReplayConfig replay_;
  NowNs now_;
  std::uint64_t read_ = 0;
  int failures_ = 0;
};

Expected<std::vector<std::string>> readTimestampLines(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) return ioError(file.string() + ": cannot be read");
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    lines.push_back(line);
  }
  while (!lines.empty() && lines.back().empty()) lines.pop_back();
  return lines;
}

}  // namespace

const char* frameFailureName(FrameFailure failure) {
  switch (failure) {
    case FrameFailure::kUnreadable: return "unreadable";
    case FrameFailure::kUnknownFormat: return "unknown_format";
    case FrameFailure::kBadHeader: return "bad_header";
    case FrameFailure::kTooLarge: return "too_large";
    case FrameFailure::kDecodeFailed: return "decode_failed";
    case FrameFailure::kNotColour: return "not_colour";
    case FrameFailure::kGrabFailed: return "grab_failed";
  }
  return "unknown";
}

SourceFrame readImageFile(const std::filesystem::path& path, std::uint64_t max_pixels) {
  const std::string name = path.string();
  std::error_code ec;
  const std::uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) return unreadable(name, FrameFailure::kUnreadable, name + ": cannot be read (" + ec.message() + ")");
  if (const std::uint64_t most = maxFileBytes(max_pixels); size > most) {
    return unreadable(name, FrameFailure::kTooLarge,
                      name + ": a file of " + std::to_string(size) + " bytes, more than an image of the camera's " +
                          "max_image_pixels " + std::to_string(max_pixels) + " can take (" + std::to_string(most) +
                          " bytes); not read");
  }
  // The header from the file's first bytes (more only for a JPEG whose frame header follows more
  // metadata than that); the rest only for an image within the limit. The bytes whose header was
  // checked are the bytes decoded.
  std::ifstream in(path, std::ios::binary);
  std::vector<std::uint8_t> bytes;
  const auto readUpTo = [&](std::uint64_t total) {
    const std::size_t had = bytes.size();
    bytes.resize(static_cast<std::size_t>(total));
    return static_cast<bool>(in.read(reinterpret_cast<char*>(bytes.data() + had), static_cast<std::streamsize>(total - had)));
  };
  constexpr std::uint64_t kHeaderBytes = 64 * 1024;
  if (!in || !readUpTo(std::min(size, kHeaderBytes))) {
    return unreadable(name, FrameFailure::kUnreadable, name + ": cannot be read");
  }
  if (!imageFormatOf(bytes)) {
    return unreadable(name, FrameFailure::kUnknownFormat, name + ": not a PNG, JPEG, BMP or PNM image (unknown format)");
  }
  Expected<ImageHeader> header = readImageHeader(bytes);
  if (!header && bytes.size() < size) {
    if (!readUpTo(size)) return unreadable(name, FrameFailure::kUnreadable, name + ": cannot be read");
    header = readImageHeader(bytes);
  }
  if (!header) return unreadable(name, FrameFailure::kBadHeader, name + ": " + header.error().message);
  const std::string what = sizeText(header->width, header->height) + " " + imageFormatName(header->format);
  if (header->pixels() > max_pixels) {
    return unreadable(name, FrameFailure::kTooLarge,
                      name + ": " + what + ", above the camera's max_image_pixels of " + std::to_string(max_pixels) +
                          "; not decoded");
  }
  if (bytes.size() < size && !readUpTo(size)) return unreadable(name, FrameFailure::kUnreadable, name + ": cannot be read");
  cv::Mat image;
  try {
    image = cv::imdecode(bytes, cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    return unreadable(name, FrameFailure::kDecodeFailed, name + ": a " + what + " that cannot be decoded (" + e.what() + ")");
  }
  if (image.empty()) return unreadable(name, FrameFailure::kDecodeFailed, name + ": a " + what + " that cannot be decoded");
  if (std::optional<SourceFrame> refused = refuseLargeFrame(image, name, max_pixels)) return std::move(*refused);
  SourceFrame f;
  f.outcome = FrameOutcome::kFrame;
  f.image_bgr = std::move(image);
  f.origin = name;
  return f;
}

Expected<std::int64_t> parseKittiTimestamp(const std::string& text) {
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0, used = 0;
  const auto bad = [&text] {
    return invalidArgument("'" + text + "' is not a timestamp YYYY-MM-DD HH:MM:SS.nnnnnnnnn");
  };
  if (std::sscanf(text.c_str(), "%4d-%2d-%2d %2d:%2d:%2d%n", &year, &month, &day, &hour, &minute, &second, &used) != 6) {
    return bad();
  }
  if (month < 1 || month > 12 || day < 1 || day > 31 || hour > 23 || minute > 59 || second > 60 || hour < 0 ||
      minute < 0 || second < 0) {
    return bad();
  }
  std::int64_t fraction_ns = 0;
  std::size_t at = static_cast<std::size_t>(used);
  if (at < text.size() && text[at] == '.') {
    ++at;
    std::int64_t scale = 100'000'000;
    std::size_t digits = 0;
    for (; at < text.size() && std::isdigit(static_cast<unsigned char>(text[at])) != 0; ++at, ++digits) {
      if (digits >= 9) return bad();
      fraction_ns += (text[at] - '0') * scale;
      scale /= 10;
    }
    if (digits == 0) return bad();
  }
  while (at < text.size() && std::isspace(static_cast<unsigned char>(text[at])) != 0) ++at;
  if (at != text.size()) return bad();
  const std::int64_t days = daysFromCivil(year, static_cast<unsigned>(month), static_cast<unsigned>(day));
  const std::int64_t seconds = days * 86400 + hour * 3600 + minute * 60 + second;
  return seconds * kNsPerSecond + fraction_ns;
}

Expected<std::unique_ptr<FrameSource>> openImageDirectory(const std::filesystem::path& directory,
                                                          const ReplayConfig& replay) {
  if (const Status s = checkReplay(replay, directory.string()); !s) return s.error();
  std::error_code ec;
  std::vector<std::filesystem::path> images;
  for (std::filesystem::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec) && isImageFile(it->path())) images.push_back(it->path());
  }
  if (ec) return ioError(directory.string() + ": cannot list the directory (" + ec.message() + ")");
  if (images.empty()) return notFound(directory.string() + ": no .png or .jpg image");
  std::sort(images.begin(), images.end());

  // KITTI raw keeps timestamps.txt beside data/, other layouts beside the images.
  std::filesystem::path timestamps = directory / "timestamps.txt";
  if (!std::filesystem::exists(timestamps) && directory.filename() == "data") {
    timestamps = directory.parent_path() / "timestamps.txt";
  }
  const std::int64_t period = periodNs(replay.rate_hz);
  std::vector<std::int64_t> offsets(images.size());
  std::int64_t pass_ns = 0;
  std::string timing;
  if (std::filesystem::exists(timestamps)) {
    Expected<std::vector<std::string>> lines = readTimestampLines(timestamps);
    if (!lines) return lines.error();
    if (lines->size() != images.size()) {
      return invalidArgument(timestamps.string() + ": " + std::to_string(lines->size()) + " timestamp(s) for " +
                             std::to_string(images.size()) + " image(s); one a line, one per image");
    }
    std::int64_t first = 0;
    for (std::size_t i = 0; i < lines->size(); ++i) {
      Expected<std::int64_t> t = parseKittiTimestamp((*lines)[i]);
      if (!t) return invalidArgument(timestamps.string() + ":" + std::to_string(i + 1) + ": " + t.error().message);
      if (i == 0) first = *t;
      offsets[i] = *t - first;
      if (i > 0 && offsets[i] < offsets[i - 1]) {
        return invalidArgument(timestamps.string() + ":" + std::to_string(i + 1) + ": goes back in time");
      }
    }
    const std::int64_t span = offsets.back();
    // The next pass starts one mean interval after the last image, as if the recording went on.
    pass_ns = span + (images.size() > 1 && span > 0 ? span / static_cast<std::int64_t>(images.size() - 1) : period);
    timing = "timed by " + timestamps.string();
  } else {
    for (std::size_t i = 0; i < images.size(); ++i) offsets[i] = static_cast<std::int64_t>(i) * period;
    pass_ns = static_cast<std::int64_t>(images.size()) * period;
    std::ostringstream out;
    out << "at " << replay.rate_hz << " Hz";
    timing = out.str();
  }
  return std::unique_ptr<FrameSource>(
      new ImageDirectorySource(directory, std::move(images), std::move(offsets), pass_ns, std::move(timing), replay));
}

Expected<std::unique_ptr<FrameSource>> openVideoFile(const std::filesystem::path& file, const ReplayConfig& replay) {
  if (const Status s = checkReplay(replay, file.string()); !s) return s.error();
  cv::VideoCapture capture;
  try {
    capture.open(file.string(), cv::CAP_ANY);
  } catch (const cv::Exception& e) {
    return ioError(file.string() + ": cannot be opened as a video (" + e.what() + ")");
  }
  if (!capture.isOpened()) return ioError(file.string() + ": cannot be opened as a video");
  const double fps = capture.get(cv::CAP_PROP_FPS);
  const double rate = fps > 0.0 && std::isfinite(fps) ? fps : replay.rate_hz;
  return std::unique_ptr<FrameSource>(new VideoFileSource(file, std::move(capture), rate, replay));
}

bool isVideoDevice(const std::filesystem::path& source) {
  const std::string s = source.string();
  const std::string prefix = "/dev/video";
  return s.size() > prefix.size() && s.compare(0, prefix.size(), prefix) == 0 &&
         std::all_of(s.begin() + static_cast<std::ptrdiff_t>(prefix.size()), s.end(),
                     [](unsigned char c) { return std::isdigit(c) != 0; });
}

Expected<std::unique_ptr<FrameSource>> openVideoDevice(const std::filesystem::path& device, const ReplayConfig& replay,
                                                       NowNs now) {
  if (!isVideoDevice(device)) return invalidArgument(device.string() + ": not a V4L2 device path /dev/videoN");
  cv::VideoCapture capture;
  try {
    capture.open(device.string(), cv::CAP_V4L2);
  } catch (const cv::Exception& e) {
    return ioError(device.string() + ": cannot be opened (" + e.what() + ")");
  }
  if (!capture.isOpened()) return ioError(device.string() + ": cannot be opened as a V4L2 camera");
  return std::unique_ptr<FrameSource>(new VideoDeviceSource(device, std::move(capture), replay, std::move(now)));
}

Expected<std::unique_ptr<FrameSource>> openFrameSource(const CameraNodeConfig& camera, NowNs now) {
  if (camera.simulated()) {
    return invalidArgument("source sim has no images: it goes with detector kind truth");
  }
  const ReplayConfig replay{camera.rate_hz, camera.loop, camera.frames, camera.max_image_pixels};
  if (isVideoDevice(camera.source)) return openVideoDevice(camera.source, replay, std::move(now));
  std::error_code ec;
  if (std::filesystem::is_directory(camera.source, ec)) return openImageDirectory(camera.source, replay);
  if (std::filesystem::is_regular_file(camera.source, ec)) return openVideoFile(camera.source, replay);
  return notFound(camera.source.string() + ": no such directory, video file or device");
}

}  // namespace fogmap
