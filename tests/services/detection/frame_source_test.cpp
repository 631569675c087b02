#include "services/detection/frame_source.hpp"

#include <gtest/gtest.h>

#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <opencv2/videoio.hpp>

namespace fogmap {
namespace {

const std::filesystem::path kSourceDir = FOGMAP_SOURCE_DIR;
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
