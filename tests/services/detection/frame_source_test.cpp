#include "services/detection/frame_source.hpp"

#include <gtest/gtest.h>

#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>
#include <zlib.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "common/config/camera_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_yaml.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

using test_support::kSourceDir;
const std::filesystem::path kKittiImages = kSourceDir / "data/kitti_raw_seq_a/image_02";

// A fresh directory under the system's temporary directory, removed at the end of the test.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() /
              ("fogmap_frame_source_" + name + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

void writeText(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

std::vector<SourceFrame> drain(FrameSource& source, std::size_t at_most = 100) {
  std::vector<SourceFrame> frames;
  for (std::size_t i = 0; i < at_most; ++i) {
    SourceFrame f = source.next();
    if (f.outcome == FrameOutcome::kDone) break;
    frames.push_back(std::move(f));
  }
  return frames;
}

TEST(ImageDirectorySource, ReplaysTheBundledKittiImagesInNameOrderAtTheRate) {
  auto source = openImageDirectory(kKittiImages, ReplayConfig{10.0, false, std::nullopt});
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<SourceFrame> frames = drain(**source);
  ASSERT_EQ(frames.size(), 3u);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    ASSERT_EQ(frames[i].outcome, FrameOutcome::kFrame) << frames[i].problem;
    EXPECT_EQ(std::filesystem::path(frames[i].origin).filename(), "000000000" + std::to_string(i) + ".png");
    ASSERT_TRUE(frames[i].due_ns.has_value());
    EXPECT_EQ(*frames[i].due_ns, static_cast<std::int64_t>(i) * 100'000'000);
    EXPECT_FALSE(frames[i].capture_time_ns.has_value());
    EXPECT_EQ(frames[i].image_bgr.type(), CV_8UC3);
    EXPECT_EQ(frames[i].image_bgr.cols, 1242);
    EXPECT_EQ(frames[i].image_bgr.rows, 375);
  }
  EXPECT_EQ((*source)->next().outcome, FrameOutcome::kDone);
}

TEST(ImageDirectorySource, LoopingContinuesTheTimelineUpToTheFrameLimit) {
  auto source = openImageDirectory(kKittiImages, ReplayConfig{20.0, true, 5});
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<SourceFrame> frames = drain(**source);
  ASSERT_EQ(frames.size(), 5u);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(*frames[i].due_ns, static_cast<std::int64_t>(i) * 50'000'000) << "frame " << i;
    EXPECT_EQ(std::filesystem::path(frames[i].origin).filename(), "000000000" + std::to_string(i % 3) + ".png");
  }
}

TEST(ImageDirectorySource, KittiTimestampsGiveTheRelativeTiming) {
  ScratchDir dir("timestamps");
  std::filesystem::create_directories(dir.path() / "data");
  for (int i = 0; i < 3; ++i) {
    const std::string name = "000000000" + std::to_string(i) + ".png";
    std::filesystem::copy_file(kKittiImages / name, dir.path() / "data" / name);
  }
  // KITTI raw keeps timestamps.txt beside data/.
  writeText(dir.path() / "timestamps.txt",
            "2011-09-26 13:02:25.964389445\n2011-09-26 13:02:26.074745312\n2011-09-26 13:02:26.189908042\n");
  auto source = openImageDirectory(dir.path() / "data", ReplayConfig{10.0, true, 4});
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<SourceFrame> frames = drain(**source);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(*frames[0].due_ns, 0);
  EXPECT_EQ(*frames[1].due_ns, 110'355'867);
  EXPECT_EQ(*frames[2].due_ns, 225'518'597);
  // The next pass starts one mean interval after the last image.
  EXPECT_EQ(*frames[3].due_ns, 225'518'597 + 225'518'597 / 2);
}

TEST(ImageDirectorySource, RefusesTimestampsThatDoNotMatchTheImages) {
  ScratchDir dir("bad_timestamps");
  std::filesystem::copy_file(kKittiImages / "0000000000.png", dir.path() / "a.png");
  std::filesystem::copy_file(kKittiImages / "0000000001.png", dir.path() / "b.png");
  writeText(dir.path() / "timestamps.txt", "2011-09-26 13:02:25.964389445\n");
  auto fewer = openImageDirectory(dir.path(), ReplayConfig{});
  ASSERT_FALSE(fewer.ok());
  EXPECT_NE(fewer.error().message.find("1 timestamp(s) for 2 image(s)"), std::string::npos) << fewer.error().message;

  writeText(dir.path() / "timestamps.txt", "2011-09-26 13:02:25.964389445\n2011-09-26 13:02:24.0\n");
  auto backwards = openImageDirectory(dir.path(), ReplayConfig{});
  ASSERT_FALSE(backwards.ok());
  EXPECT_NE(backwards.error().message.find("timestamps.txt:2"), std::string::npos) << backwards.error().message;
}

TEST(ImageDirectorySource, AnUnreadableImageIsSkippedAndReportedWithItsPath) {
  ScratchDir dir("unreadable");
  std::filesystem::copy_file(kKittiImages / "0000000000.png", dir.path() / "0.png");
  writeText(dir.path() / "1.png", "this is not a png");
  std::filesystem::copy_file(kKittiImages / "0000000002.png", dir.path() / "2.png");
  auto source = openImageDirectory(dir.path(), ReplayConfig{10.0, false, std::nullopt});
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<SourceFrame> frames = drain(**source);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].outcome, FrameOutcome::kFrame);
  EXPECT_EQ(frames[1].outcome, FrameOutcome::kUnreadable);
  EXPECT_NE(frames[1].problem.find((dir.path() / "1.png").string()), std::string::npos) << frames[1].problem;
  EXPECT_TRUE(frames[1].image_bgr.empty());
  EXPECT_EQ(frames[2].outcome, FrameOutcome::kFrame);
  EXPECT_EQ(*frames[2].due_ns, 200'000'000);  // the unreadable image keeps its slot
}

TEST(ImageDirectorySource, ALoopWithoutAnyReadableImageEnds) {
  ScratchDir dir("all_unreadable");
  writeText(dir.path() / "a.png", "junk");
  auto source = openImageDirectory(dir.path(), ReplayConfig{10.0, true, std::nullopt});
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ(drain(**source).size(), 1u);
}

TEST(ImageDirectorySource, ADirectoryWithoutImagesIsRefused) {
  ScratchDir dir("empty");
  writeText(dir.path() / "notes.txt", "no images here");
  auto source = openImageDirectory(dir.path(), ReplayConfig{});
  ASSERT_FALSE(source.ok());
  EXPECT_EQ(source.error().code, ErrorCode::kNotFound);
}

TEST(VideoFileSource, ReplaysAVideoAtItsOwnFrameRate) {
  ScratchDir dir("video");
  const std::filesystem::path file = dir.path() / "clip.avi";
  {
    // OpenCV's own MJPEG writer: no codec library needed.
    cv::VideoWriter writer(file.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25.0,
                           cv::Size(64, 48));
    if (!writer.isOpened()) GTEST_SKIP() << "this OpenCV cannot write MJPEG";
    for (int i = 0; i < 4; ++i) writer.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(40.0 * i, 0, 0)));
  }
  auto source = openVideoFile(file, ReplayConfig{10.0, true, 6});
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<SourceFrame> frames = drain(**source);
  ASSERT_EQ(frames.size(), 6u);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    ASSERT_EQ(frames[i].outcome, FrameOutcome::kFrame) << frames[i].problem;
    EXPECT_EQ(*frames[i].due_ns, static_cast<std::int64_t>(i) * 40'000'000) << "frame " << i << " (25 Hz, looped)";
    EXPECT_EQ(frames[i].image_bgr.size(), cv::Size(64, 48));
  }
}

// ---- Bounded input -----------------------------------------------------------------------------

void appendBigEndian(std::string& out, std::uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((value >> shift) & 0xFF);
}

void appendChunk(std::string& png, const std::string& type, const std::string& data) {
  appendBigEndian(png, static_cast<std::uint32_t>(data.size()));
  const std::string body = type + data;
  png += body;
  appendBigEndian(png, static_cast<std::uint32_t>(
                           ::crc32(0, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()))));
}

// A valid 8-bit greyscale PNG of one colour: every row zeros, deflated row by row. At 20,000 x
// 20,000 it is about 389 kB on disk and 400 MB of pixels (1.2 GB as the BGR a decoder would make).
void writeOneColourPng(const std::filesystem::path& file, std::uint32_t width, std::uint32_t height) {
  std::string ihdr;
  appendBigEndian(ihdr, width);
  appendBigEndian(ihdr, height);
  ihdr += std::string("\x08\x00\x00\x00\x00", 5);  // depth 8, greyscale, deflate, no filter, not interlaced
  z_stream z{};
  ASSERT_EQ(::deflateInit(&z, Z_BEST_COMPRESSION), Z_OK);
  const std::string row(width + 1, '\0');  // filter byte 0, then the pixels
  std::string idat;
  std::string buffer(1 << 16, '\0');
  for (std::uint32_t y = 0; y <= height; ++y) {
    const bool last = y == height;
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(row.data()));
    z.avail_in = last ? 0 : static_cast<uInt>(row.size());
    do {
      z.next_out = reinterpret_cast<Bytef*>(buffer.data());
      z.avail_out = static_cast<uInt>(buffer.size());
      ASSERT_NE(::deflate(&z, last ? Z_FINISH : Z_NO_FLUSH), Z_STREAM_ERROR);
      idat.append(buffer.data(), buffer.size() - z.avail_out);
    } while (z.avail_out == 0);
  }
  ::deflateEnd(&z);
  std::string png("\x89PNG\r\n\x1a\n", 8);
  appendChunk(png, "IHDR", ihdr);
  appendChunk(png, "IDAT", idat);
  appendChunk(png, "IEND", "");
  writeText(file, png);
}

// The process's peak resident set so far, in kB.
long peakRssKb() {
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

TEST(ImageDirectorySource, AHugePngIsRefusedByNameFromItsHeaderWithoutDecodingIt) {
  ScratchDir dir("huge_png");
  const std::filesystem::path huge = dir.path() / "huge.png";
  writeOneColourPng(huge, 20000, 20000);
  ASSERT_LT(std::filesystem::file_size(huge), 1u << 20) << "the test wants a small file of a huge image";
  std::filesystem::copy_file(kKittiImages / "0000000000.png", dir.path() / "kitti.png");
  auto source = openImageDirectory(dir.path(), ReplayConfig{10.0, false, std::nullopt});
  ASSERT_TRUE(source.ok()) << source.error().message;

  const long rss_before_kb = peakRssKb();
  const std::vector<SourceFrame> frames = drain(**source);
  const long rss_growth_kb = peakRssKb() - rss_before_kb;

  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].outcome, FrameOutcome::kUnreadable);
  EXPECT_EQ(frames[0].failure, FrameFailure::kTooLarge);
  EXPECT_NE(frames[0].problem.find(huge.string()), std::string::npos) << frames[0].problem;
  EXPECT_NE(frames[0].problem.find("20000 x 20000"), std::string::npos) << frames[0].problem;
  EXPECT_NE(frames[0].problem.find(std::to_string(camera::kDefaultMaxImagePixels)), std::string::npos) << frames[0].problem;
  EXPECT_TRUE(frames[0].image_bgr.empty());
  // Decoded, the image would be 1.2 GB of BGR: the refusal allocates nothing of the kind (the peak
  // covers the KITTI frame read after it, 1.4 MB).
  EXPECT_LT(rss_growth_kb, 64 * 1024) << "peak RSS grew by " << rss_growth_kb << " kB";
  EXPECT_EQ(frames[1].outcome, FrameOutcome::kFrame) << frames[1].problem;
  EXPECT_EQ(frames[1].image_bgr.size(), cv::Size(1242, 375));
}

TEST(ImageDirectorySource, ThePixelLimitIsTheCamerasAndBoundsAtItsValue) {
  constexpr std::uint64_t kKittiPixels = 1242 * 375;
  EXPECT_EQ(readImageFile(kKittiImages / "0000000000.png", kKittiPixels).outcome, FrameOutcome::kFrame);
  const SourceFrame refused = readImageFile(kKittiImages / "0000000000.png", kKittiPixels - 1);
  EXPECT_EQ(refused.outcome, FrameOutcome::kUnreadable);
  EXPECT_EQ(refused.failure, FrameFailure::kTooLarge);
  EXPECT_NE(refused.problem.find("1242 x 375"), std::string::npos) << refused.problem;
  // The same for a JPEG, whose size is in its frame header.
  ScratchDir dir("jpeg_limit");
  const cv::Mat image = cv::imread((kKittiImages / "0000000000.png").string());
  ASSERT_TRUE(cv::imwrite((dir.path() / "frame.jpg").string(), image));
  EXPECT_EQ(readImageFile(dir.path() / "frame.jpg", kKittiPixels).outcome, FrameOutcome::kFrame);
  EXPECT_EQ(readImageFile(dir.path() / "frame.jpg", kKittiPixels - 1).failure, FrameFailure::kTooLarge);
}

TEST(ImageDirectorySource, EveryUnreadableFileIsRefusedByNameWithItsReason) {
  ScratchDir dir("reasons");
  writeText(dir.path() / "text.png", "this is not a png");
  std::string png;
  {
    std::vector<std::uint8_t> bytes;
    cv::imencode(".png", cv::Mat(8, 8, CV_8UC3, cv::Scalar(1, 2, 3)), bytes);
    png.assign(bytes.begin(), bytes.end());
  }
  writeText(dir.path() / "cut.png", png.substr(0, 20));                    // inside IHDR
  writeText(dir.path() / "corrupt.png", png.substr(0, 33) + "garbage");    // a good IHDR, no image data
  // A file larger than any image within the limit could be: refused unread.
  writeText(dir.path() / "padded.png", png + std::string((1 << 20) + 1024, '\0'));
  const std::vector<std::pair<std::string, FrameFailure>> cases{{"text.png", FrameFailure::kUnknownFormat},
                                                                {"cut.png", FrameFailure::kBadHeader},
                                                                {"corrupt.png", FrameFailure::kDecodeFailed},
                                                                {"padded.png", FrameFailure::kTooLarge},
                                                                {"absent.png", FrameFailure::kUnreadable}};
  for (const auto& [name, failure] : cases) {
    SCOPED_TRACE(name);
    const SourceFrame f = readImageFile(dir.path() / name, 100);
    EXPECT_EQ(f.outcome, FrameOutcome::kUnreadable);
    EXPECT_EQ(frameFailureName(f.failure), std::string(frameFailureName(failure)));
    EXPECT_NE(f.problem.find((dir.path() / name).string()), std::string::npos) << f.problem;
    EXPECT_EQ(f.origin, (dir.path() / name).string());
  }
}

TEST(VideoFileSource, AVideoWhoseFramesAreTooLargeIsRefusedOnceUnreadAndEnds) {
  ScratchDir dir("video_large");
  const std::filesystem::path file = dir.path() / "clip.avi";
  {
    cv::VideoWriter writer(file.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25.0,
                           cv::Size(64, 48));
    if (!writer.isOpened()) GTEST_SKIP() << "this OpenCV cannot write MJPEG";
    for (int i = 0; i < 4; ++i) writer.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(40.0 * i, 0, 0)));
  }
  ReplayConfig replay{10.0, true, std::nullopt};
  replay.max_pixels = 64 * 48 - 1;
  auto source = openVideoFile(file, replay);
  ASSERT_TRUE(source.ok()) << source.error().message;
  const std::vector<SourceFrame> frames = drain(**source);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].failure, FrameFailure::kTooLarge);
  EXPECT_NE(frames[0].problem.find(file.string()), std::string::npos) << frames[0].problem;
  EXPECT_NE(frames[0].problem.find("64 x 48"), std::string::npos) << frames[0].problem;

  replay.max_pixels = 64 * 48;
  auto fits = openVideoFile(file, replay);
  ASSERT_TRUE(fits.ok());
  EXPECT_EQ((*fits)->next().outcome, FrameOutcome::kFrame);
}

TEST(CameraTopology, MaxImagePixelsIsReadWrittenAndBounded) {
  ScratchDir dir("topology");
  const std::string head = R"(name: t
nodes:
  - {name: root, id: 100, role: aggregator, host: 127.0.0.1, port: 7001, metrics_port: 9102}
  - {name: tracker, id: 50, role: tracker, host: 127.0.0.1, port: 7000, metrics_port: 9100}
  - name: cam
    id: 20
    role: detection
    parent: tracker
    host: 127.0.0.1
    metrics_port: 9101
    camera:
      source: images
)";
  const std::string calibration = R"(      calibration: {fx: 700, fy: 700, cx: 600, cy: 180, width: 1242, height: 375,
                    pose: {translation_m: [0, 0, 1.6], rpy_deg: [-90, 0, -90]}}
)";
  const auto load = [&](const std::string& line) {
    writeText(dir.path() / "t.yaml", head + line + calibration);
    return loadTopology(dir.path() / "t.yaml");
  };
  const auto defaulted = load("");
  ASSERT_TRUE(defaulted.ok()) << defaulted.error().message;
  EXPECT_EQ(defaulted->find("cam")->camera->max_image_pixels, camera::kDefaultMaxImagePixels);
  EXPECT_EQ(toYaml(*defaulted).find("max_image_pixels"), std::string::npos) << "the default is not written";

  const auto set = load("      max_image_pixels: 500000\n");
  ASSERT_TRUE(set.ok()) << set.error().message;
  EXPECT_EQ(set->find("cam")->camera->max_image_pixels, 500000u);
  writeText(dir.path() / "again.yaml", toYaml(*set));
  const auto again = loadTopology(dir.path() / "again.yaml");
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(again->find("cam")->camera->max_image_pixels, 500000u);

  for (const std::string bad : {"0", "-1", "268435457", "lots"}) {
    const auto refused = load("      max_image_pixels: " + bad + "\n");
    ASSERT_FALSE(refused.ok()) << bad;
    EXPECT_NE(refused.error().message.find("max_image_pixels"), std::string::npos) << refused.error().message;
  }
}

TEST(KittiTimestamp, ParsesToUnixNanoseconds) {
  std::tm tm{};
  tm.tm_year = 2011 - 1900;
  tm.tm_mon = 8;
  tm.tm_mday = 26;
  tm.tm_hour = 13;
  tm.tm_min = 2;
  tm.tm_sec = 25;
  const std::int64_t seconds = ::timegm(&tm);
  const auto parsed = parseKittiTimestamp("2011-09-26 13:02:25.964389445");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(*parsed, seconds * 1'000'000'000 + 964'389'445);
  const auto short_fraction = parseKittiTimestamp("2011-09-26 13:02:25.5");
  ASSERT_TRUE(short_fraction.ok());
  EXPECT_EQ(*short_fraction, seconds * 1'000'000'000 + 500'000'000);
  EXPECT_FALSE(parseKittiTimestamp("2011-09-26T13:02:25").ok());
  EXPECT_FALSE(parseKittiTimestamp("2011-13-26 13:02:25.1").ok());
  EXPECT_FALSE(parseKittiTimestamp("2011-09-26 13:02:25.1234567890").ok());
}

TEST(FrameSource, RecognisesVideoDevicesAndRefusesSimWithoutTruth) {
  EXPECT_TRUE(isVideoDevice("/dev/video0"));
  EXPECT_TRUE(isVideoDevice("/dev/video12"));
  EXPECT_FALSE(isVideoDevice("/dev/video"));
  EXPECT_FALSE(isVideoDevice("/dev/videoX"));
  EXPECT_FALSE(isVideoDevice("clip.mp4"));
  CameraNodeConfig camera;
  camera.source = kSimSource;
  EXPECT_FALSE(openFrameSource(camera, [] { return std::int64_t{0}; }).ok());
  camera.source = kSourceDir / "data/no_such_directory";
  const auto missing = openFrameSource(camera, [] { return std::int64_t{0}; });
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
}

}  // namespace
}  // namespace fogmap
