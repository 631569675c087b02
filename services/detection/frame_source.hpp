#pragma once
// Where a detection node's images come from (topology `camera.source`): a directory of images
// replayed in name order, a video file, or a V4L2 device. A replayed source says when each frame is
// due relative to the start of the replay (from rate_hz, or from a KITTI raw timestamps.txt beside
// the images); a device's frames are stamped with the injected clock when they are grabbed. An image
// that cannot be read is reported with its path and skipped, never fatal. Every frame is bounded by
// the camera's max_image_pixels before it is decoded: an image file by its header, a video or a
// device by the size the capture reports. No gRPC, no printing.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "common/camera/image_limits.hpp"
#include "common/base/clock.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap {

enum class FrameOutcome {
  kFrame,       // an image to detect on
  kUnreadable,  // this frame could not be read (`failure` and `problem` say why); the next one may be fine
  kDone,        // the source has no more frames
};

// Why a frame could not be had: the reason label of the service's failure counter.
enum class FrameFailure {
  kUnreadable,     // the file cannot be opened or read
  kUnknownFormat,  // the file is not a PNG, JPEG, BMP or PNM image
  kBadHeader,      // its header is cut short or malformed: no size to check
  kTooLarge,       // more pixels than max_image_pixels (or a file larger than such an image can be)
  kDecodeFailed,   // the header was fine, the decoder was not
  kNotColour,      // a video or device frame that is not 8-bit BGR
  kGrabFailed,     // the device gave no frame
};
const char* frameFailureName(FrameFailure failure);  // "unreadable", "unknown_format", ...

// Every failure, for counters that list their reasons up front.
inline constexpr FrameFailure kFrameFailures[] = {FrameFailure::kUnreadable,   FrameFailure::kUnknownFormat,
                                                  FrameFailure::kBadHeader,    FrameFailure::kTooLarge,
                                                  FrameFailure::kDecodeFailed, FrameFailure::kNotColour,
                                                  FrameFailure::kGrabFailed};

struct SourceFrame {
  FrameOutcome outcome = FrameOutcome::kDone;
  cv::Mat image_bgr;  // 8-bit, 3 channels; empty unless kFrame
  // Replayed sources: when the frame is due, in ns after the replay's first frame.
  std::optional<std::int64_t> due_ns;
  // Live sources: the capture time (unix ns) from the injected clock.
  std::optional<std::int64_t> capture_time_ns;
  std::string origin;   // the file (or device and frame) the frame came from
  FrameFailure failure = FrameFailure::kUnreadable;  // kUnreadable: why
  std::string problem;  // kUnreadable: the path and what went wrong (sizes included when too large)
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // The next frame, an unreadable frame, or kDone; never blocks on anything but the device.
  virtual SourceFrame next() = 0;
  // One line for logs: what is replayed and how.
  virtual std::string describe() const = 0;
};

// How a replay is paced and bounded (from CameraNodeConfig).
struct ReplayConfig {
  double rate_hz = 10.0;                // frames a second when no timestamps say otherwise
  bool loop = true;                     // start again after the last frame
  std::optional<std::uint64_t> frames;  // stop after this many frames (unreadable ones included)
  std::uint64_t max_pixels = camera::kDefaultMaxImagePixels;  // larger frames are refused undecoded
};

// One image file as 8-bit BGR, or why not: the header read first and checked against
// `max_pixels` (and the file's size against what such an image can take) before any decoding.
// kFrame or kUnreadable; `origin` is the path, `problem` names it. No timing.
SourceFrame readImageFile(const std::filesystem::path& path, std::uint64_t max_pixels);

// The unix time in ns of a KITTI raw timestamp "YYYY-MM-DD HH:MM:SS.nnnnnnnnn" (UTC; fewer fraction
// digits are allowed); an error quoting the text otherwise.
Expected<std::int64_t> parseKittiTimestamp(const std::string& text);

// Every image (.png, .jpg, .jpeg, any case) of `directory` in name order. The timing comes from
// `timestamps.txt` in the directory (or beside it when the directory is KITTI raw's `data/`), one
// line per image, relative to the first; without one from `replay.rate_hz`. An error when there is
// no image, or the timestamps file does not parse, goes backwards or has another number of lines.
Expected<std::unique_ptr<FrameSource>> openImageDirectory(const std::filesystem::path& directory,
                                                          const ReplayConfig& replay);

// A video file read with OpenCV, due at its own frame rate (rate_hz when the file has none). When the
// capture reports frames above replay.max_pixels, the first frame is refused (too large) unread and
// the source is done.
Expected<std::unique_ptr<FrameSource>> openVideoFile(const std::filesystem::path& file, const ReplayConfig& replay);

// A V4L2 device (/dev/videoN), live: frames stamped with `now` as they are grabbed. A device that
// fails many grabs in a row is done, as is one whose frame size is above replay.max_pixels.
Expected<std::unique_ptr<FrameSource>> openVideoDevice(const std::filesystem::path& device, const ReplayConfig& replay,
                                                       NowNs now);

// True for a V4L2 device path (/dev/videoN).
bool isVideoDevice(const std::filesystem::path& source);

// The source a camera node names: a directory, a device or a video file. Source sim has no images
// (it replays truth): an error, as is a path that does not exist.
Expected<std::unique_ptr<FrameSource>> openFrameSource(const CameraNodeConfig& camera, NowNs now);

}  // namespace fogmap
