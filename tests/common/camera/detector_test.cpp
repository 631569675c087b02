// Camera detection: HOG against KITTI's own pedestrian label, cascades on a real image, networks
// whose output the test knows (built at test time by tests/data/make_tiny_detector.py), the config
// checks and the frame queue between a camera and a slower detector.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <latch>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/detector.hpp"
#include "common/camera/frame_queue.hpp"
#include "common/camera/kitti.hpp"
#include "tests/support/source_dir.hpp"
#include "tests/support/tiny_detector.hpp"

namespace fogmap::camera {
namespace {

namespace fs = std::filesystem;
using test_support::dataDir;
using test_support::makeTinyDetector;
using test_support::pythonWithOnnx;

// Debian's opencv-data (tools/install-deps.sh); the library itself takes cascades only from config.
const fs::path kHaarDir = "/usr/share/opencv4/haarcascades";

std::string slurp(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void writeFile(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

// A fresh directory under the system's temporary one, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    std::random_device seed;
    path_ = fs::temp_directory_path() / ("fogmap-detector-test-" + std::to_string(seed()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

DnnConfig tinyDnn(const fs::path& model, const fs::path& names, DnnOutput output) {
  DnnConfig c;
  c.model_path = model.string();
  c.names_path = names.string();
  c.output = output;
  c.input_width = 32;
  c.input_height = 32;
  c.confidence_threshold = 0.5;
  c.nms_threshold = 0.45;
  return c;
}

Expected<std::vector<Detection>> detectWith(const DetectorConfig& config, const cv::Mat& image) {
  Expected<std::unique_ptr<Detector>> detector = makeDetector(config);
  if (!detector) return detector.error();
  return (*detector)->detect(image, "cam0", 42);
}

void expectBox(const Box2d& actual, const Box2d& expected) {
  constexpr double kTolerancePx = 1e-3;  // float32 network outputs times the image size
  EXPECT_NEAR(actual.left, expected.left, kTolerancePx);
  EXPECT_NEAR(actual.top, expected.top, kTolerancePx);
  EXPECT_NEAR(actual.right, expected.right, kTolerancePx);
  EXPECT_NEAR(actual.bottom, expected.bottom, kTolerancePx);
}

void expectWellFormedInside(const std::vector<Detection>& detections, const cv::Size& image) {
  for (const Detection& d : detections) {
    EXPECT_GE(d.box.left, 0.0);
    EXPECT_GE(d.box.top, 0.0);
    EXPECT_LE(d.box.right, image.width);
    EXPECT_LE(d.box.bottom, image.height);
    EXPECT_LT(d.box.left, d.box.right);
    EXPECT_LT(d.box.top, d.box.bottom);
    EXPECT_EQ(d.camera, "cam0");
    EXPECT_EQ(d.capture_time_ns, 42);
  }
}

// ---- IoU and NMS --------------------------------------------------------------------------------

TEST(Iou, MatchesHandComputedOverlaps) {
  const Box2d a{0, 0, 2, 2};
  EXPECT_DOUBLE_EQ(iou(a, a), 1.0);
  EXPECT_DOUBLE_EQ(iou(a, Box2d{1, 1, 3, 3}), 1.0 / 7.0);  // 1 shared of 4 + 4 - 1
  EXPECT_DOUBLE_EQ(iou(Box2d{1, 1, 3, 3}, a), 1.0 / 7.0);
  EXPECT_DOUBLE_EQ(iou(a, Box2d{0, 0, 2, 1}), 0.5);        // one inside the other
  EXPECT_DOUBLE_EQ(iou(a, Box2d{2, 0, 4, 2}), 0.0);        // touching edges share no area
  EXPECT_DOUBLE_EQ(iou(Box2d{}, Box2d{}), 0.0);            // empty boxes overlap nothing
}

TEST(NonMaximumSuppression, KeepsTheBestOfOverlappingBoxesOfOneLabel) {
  const std::vector<Detection> raw{
      {{0, 0, 10, 10}, "person", 0.6, "", 0},
      {{1, 0, 11, 10}, "person", 0.9, "", 0},   // IoU 9/11 with the first: suppresses it
      {{1, 0, 11, 10}, "car", 0.5, "", 0},      // same place, other label: kept
      {{20, 0, 30, 10}, "person", 0.4, "", 0},  // elsewhere: kept
  };
  const std::vector<Detection> kept = nonMaximumSuppression(raw, 0.5);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[0].score, 0.9);
  EXPECT_EQ(kept[1].label, "car");
  EXPECT_EQ(kept[2].score, 0.4);
  // Above the overlap, nothing is suppressed.
  EXPECT_EQ(nonMaximumSuppression(raw, 0.95).size(), 4u);
}

// ---- HOG --------------------------------------------------------------------------------------

TEST(HogDetector, FindsThePedestrianOfKittiFrame000000) {
  const cv::Mat image = cv::imread((dataDir() / "kitti_object/image_2/000000.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const auto labels = parseKittiLabels(slurp(dataDir() / "kitti_object/label_2/000000.txt"));
  ASSERT_TRUE(labels.ok()) << labels.error().message;
  ASSERT_EQ(labels->size(), 1u);
  ASSERT_EQ(labels->front().type, "Pedestrian");
  const Box2d truth = labels->front().box;

  DetectorConfig config;
  config.kind = DetectorKind::kHog;
  config.hog.upscale = 1.5;  // the pedestrian (165 px) is found at 1 too, with a much thinner margin
  const auto detections = detectWith(config, image);
  ASSERT_TRUE(detections.ok()) << detections.error().message;
  expectWellFormedInside(*detections, image.size());

  double best = 0.0;
  for (const Detection& d : *detections) {
    EXPECT_EQ(d.label, "person");
    best = std::max(best, iou(d.box, truth));
  }
  EXPECT_GE(best, 0.5) << detections->size() << " detection(s), none on the labelled pedestrian";
  for (std::size_t i = 0; i < detections->size(); ++i) {
    for (std::size_t j = i + 1; j < detections->size(); ++j) {
      EXPECT_LE(iou((*detections)[i].box, (*detections)[j].box), config.hog.nms_iou) << "NMS left an overlapping pair";
    }
  }
}

TEST(HogDetector, FindsNoOneInAFeaturelessImage) {
  DetectorConfig config;
  const auto detections = detectWith(config, cv::Mat(300, 400, CV_8UC3, cv::Scalar(90, 120, 150)));
  ASSERT_TRUE(detections.ok()) << detections.error().message;
  EXPECT_TRUE(detections->empty());
}

TEST(HogDetector, RefusesAnImageThatIsNotBgr) {
  DetectorConfig config;
  const auto gray = detectWith(config, cv::Mat(200, 200, CV_8UC1, cv::Scalar(0)));
  ASSERT_FALSE(gray.ok());
  EXPECT_NE(gray.error().message.find("image_bgr"), std::string::npos) << gray.error().message;
  EXPECT_FALSE(detectWith(config, cv::Mat()).ok());
  auto detector = makeDetector(config);
  ASSERT_TRUE(detector.ok());
  const DetectResult result = (*detector)->detectFrame(cv::Mat(), "cam0", 42);
  ASSERT_TRUE(result.refusal.has_value());
  EXPECT_EQ(result.refusal->reason, DetectFailure::kBadImage);
}

TEST(HogDetector, RefusesAnImageWhoseUpscaledSizeIsAboveWhatItSearches) {
  DetectorConfig config;
  config.hog.upscale = 8.0;
  auto detector = makeDetector(config);
  ASSERT_TRUE(detector.ok());
  // 1100 x 1000 upscaled by 8 is 70.4 MP, above kMaxHogSearchPixels: refused before it is made.
  const DetectResult large = (*detector)->detectFrame(cv::Mat(1000, 1100, CV_8UC3, cv::Scalar(0)), "cam0", 42);
  ASSERT_TRUE(large.refusal.has_value());
  EXPECT_EQ(large.refusal->reason, DetectFailure::kTooLarge);
  EXPECT_NE(large.refusal->error.message.find("hog.upscale"), std::string::npos) << large.refusal->error.message;
  EXPECT_NE(large.refusal->error.message.find("1100 x 1000"), std::string::npos) << large.refusal->error.message;
  // A KITTI frame at the same upscale (29.8 MP) is searched.
  const DetectResult kitti = (*detector)->detectFrame(cv::Mat(375, 1242, CV_8UC3, cv::Scalar(0)), "cam0", 42);
  EXPECT_FALSE(kitti.refusal.has_value()) << kitti.refusal->error.message;
}

// ---- Cascades ---------------------------------------------------------------------------------

TEST(CascadeDetector, RunsOnAKittiImageAndReturnsBoxesInsideIt) {
  const cv::Mat image = cv::imread((dataDir() / "kitti_object/image_2/000000.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  for (const char* file : {"haarcascade_fullbody.xml", "haarcascade_frontalface_default.xml"}) {
    SCOPED_TRACE(file);
    DetectorConfig config;
    config.kind = DetectorKind::kCascade;
    config.cascade.cascade_path = (kHaarDir / file).string();
    config.cascade.label = "cascade-object";
    ASSERT_TRUE(fs::exists(config.cascade.cascade_path)) << "install opencv-data (tools/install-deps.sh)";
    const auto detections = detectWith(config, image);
    ASSERT_TRUE(detections.ok()) << detections.error().message;
    expectWellFormedInside(*detections, image.size());
    for (const Detection& d : *detections) {
      EXPECT_EQ(d.label, "cascade-object");
      EXPECT_GE(d.score, config.cascade.min_neighbors);  // windows merged: at least min_neighbors
      EXPECT_GE(d.box.width(), config.cascade.min_size_px);
    }
  }
}

TEST(CascadeDetector, FindsTheFaceInOpenCvsSamplePhoto) {
  // Debian's opencv-doc carries OpenCV's sample photos; it is 95 MB, so not a test dependency.
  const fs::path photo = "/usr/share/doc/opencv-doc/examples/data/messi5.jpg";
  if (!fs::exists(photo)) GTEST_SKIP() << "no " << photo << " (Debian: opencv-doc); the face cascade is run on KITTI only";
  const cv::Mat image = cv::imread(photo.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  const Box2d face{222, 92, 258, 131};  // annotated by hand: hairline to chin, cheek to cheek
  DetectorConfig config;
  config.kind = DetectorKind::kCascade;
  config.cascade.cascade_path = (kHaarDir / "haarcascade_frontalface_alt.xml").string();
  const auto detections = detectWith(config, image);
  ASSERT_TRUE(detections.ok()) << detections.error().message;
  expectWellFormedInside(*detections, image.size());
  double best = 0.0;
  for (const Detection& d : *detections) best = std::max(best, iou(d.box, face));
  EXPECT_GE(best, 0.5) << detections->size() << " detection(s), none on the face";
}

TEST(CascadeDetector, MissingCascadeFileIsAnErrorNamingThePath) {
  TempDir dir;
  DetectorConfig config;
  config.kind = DetectorKind::kCascade;
  config.cascade.cascade_path = (dir.path() / "no_such_cascade.xml").string();
  const auto detector = makeDetector(config);
  ASSERT_FALSE(detector.ok());
  EXPECT_EQ(detector.error().code, ErrorCode::kNotFound);
  EXPECT_NE(detector.error().message.find(config.cascade.cascade_path), std::string::npos) << detector.error().message;
  EXPECT_NE(detector.error().message.find("cascade.cascade_path"), std::string::npos) << detector.error().message;
}

TEST(CascadeDetector, AFileThatIsNotACascadeIsRefused) {
  TempDir dir;
  DetectorConfig config;
  config.kind = DetectorKind::kCascade;
  config.cascade.cascade_path = (dir.path() / "notes.xml").string();
  writeFile(config.cascade.cascade_path, "<?xml version=\"1.0\"?>\n<opencv_storage></opencv_storage>\n");
  const auto detector = makeDetector(config);
  ASSERT_FALSE(detector.ok());
  EXPECT_NE(detector.error().message.find("is not a cascade"), std::string::npos) << detector.error().message;
}

// ---- Networks (cv::dnn) -----------------------------------------------------------------------

// 200 x 100 pixels, so normalised coordinates scale differently in x and y.
cv::Mat wideImage() { return cv::Mat(100, 200, CV_8UC3, cv::Scalar(30, 60, 90)); }

TEST(DnnDetector, ParsesSsdRowsIntoImageBoxesWithNamesThresholdAndNms) {
  SKIP_WITHOUT_ONNX(python);
  TempDir dir;
  const fs::path model = makeTinyDetector(*python, dir.path(), "ssd", 32, 32,
                                          {
                                              "0,1,0.9,0.10,0.20,0.40,0.60",   // bicycle: kept
                                              "0,1,0.8,0.11,0.21,0.41,0.61",   // overlaps it, same class: suppressed
                                              "0,2,0.7,0.11,0.21,0.41,0.61",   // same place, car: kept
                                              "0,1,0.3,0.60,0.60,0.90,0.90",   // below the threshold
                                              "0,0,0.95,0.50,0.10,0.70,0.30",  // person: kept, best
                                              "0,2,0.6,0.80,0.70,1.20,1.10",   // reaches past the image: clipped
                                              "-1,0,0.99,0,0,1,1",             // padding row (no image)
                                          });
  ASSERT_FALSE(model.empty());
  writeFile(dir.path() / "names.txt", "person\nbicycle\ncar\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(model, dir.path() / "names.txt", DnnOutput::kSsd);
  const auto detections = detectWith(config, wideImage());
  ASSERT_TRUE(detections.ok()) << detections.error().message;
  expectWellFormedInside(*detections, wideImage().size());
  ASSERT_EQ(detections->size(), 4u);
  EXPECT_EQ((*detections)[0].label, "person");
  EXPECT_NEAR((*detections)[0].score, 0.95, 1e-6);
  expectBox((*detections)[0].box, {100, 10, 140, 30});
  EXPECT_EQ((*detections)[1].label, "bicycle");
  EXPECT_NEAR((*detections)[1].score, 0.9, 1e-6);
  expectBox((*detections)[1].box, {20, 20, 80, 60});
  EXPECT_EQ((*detections)[2].label, "car");
  expectBox((*detections)[2].box, {22, 21, 82, 61});
  EXPECT_EQ((*detections)[3].label, "car");
  expectBox((*detections)[3].box, {160, 70, 200, 100});

  // A lower threshold lets the 0.3 bicycle in; a looser NMS keeps the overlapping one.
  config.dnn.confidence_threshold = 0.2;
  config.dnn.nms_threshold = 0.99;
  const auto all = detectWith(config, wideImage());
  ASSERT_TRUE(all.ok()) << all.error().message;
  EXPECT_EQ(all->size(), 6u);
}

TEST(DnnDetector, ParsesDarknetYoloRowsNormalisedToTheImage) {
  SKIP_WITHOUT_ONNX(python);
  TempDir dir;
  // cx, cy, w, h, objectness, then the class scores (already times objectness, as Darknet's).
  const fs::path model = makeTinyDetector(*python, dir.path(), "yolo", 32, 32,
                                          {"0.5,0.5,0.2,0.4,0.9,0.10,0.85", "0.2,0.3,0.1,0.1,0.3,0.25,0.05"});
  ASSERT_FALSE(model.empty());
  writeFile(dir.path() / "names.txt", "person\ncar\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(model, dir.path() / "names.txt", DnnOutput::kYoloDarknet);
  const auto detections = detectWith(config, wideImage());
  ASSERT_TRUE(detections.ok()) << detections.error().message;
  ASSERT_EQ(detections->size(), 1u);
  EXPECT_EQ((*detections)[0].label, "car");
  EXPECT_NEAR((*detections)[0].score, 0.85, 1e-6);
  expectBox((*detections)[0].box, {80, 30, 120, 70});
}

TEST(DnnDetector, ParsesExportedYoloRowsInInputPixels) {
  SKIP_WITHOUT_ONNX(python);
  TempDir dir;
  // In the 32 x 32 input's pixels; the class score is multiplied by the objectness: 0.9 * 0.8.
  const fs::path model = makeTinyDetector(*python, dir.path(), "yolo", 32, 32, {"16,8,8,4,0.9,0.8,0.1"});
  ASSERT_FALSE(model.empty());
  writeFile(dir.path() / "names.txt", "person\ncar\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(model, dir.path() / "names.txt", DnnOutput::kYoloExport);
  const auto detections = detectWith(config, wideImage());
  ASSERT_TRUE(detections.ok()) << detections.error().message;
  ASSERT_EQ(detections->size(), 1u);
  EXPECT_EQ((*detections)[0].label, "person");
  EXPECT_NEAR((*detections)[0].score, 0.72, 1e-6);
  expectBox((*detections)[0].box, {75, 18.75, 125, 31.25});  // x times 200/32, y times 100/32
}

TEST(DnnDetector, AnOutputOfAnotherLayoutIsAnErrorNamingItsShape) {
  SKIP_WITHOUT_ONNX(python);
  TempDir dir;
  const fs::path model = makeTinyDetector(*python, dir.path(), "ssd", 32, 32, {"0,0,0.9,0.1,0.1,0.2,0.2"});
  ASSERT_FALSE(model.empty());
  writeFile(dir.path() / "names.txt", "person\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(model, dir.path() / "names.txt", DnnOutput::kYoloExport);
  const auto detections = detectWith(config, wideImage());
  ASSERT_FALSE(detections.ok());
  EXPECT_NE(detections.error().message.find("[1, 1, 1, 7]"), std::string::npos) << detections.error().message;
  // The refusal says why, for the service's failure counter.
  auto detector = makeDetector(config);
  ASSERT_TRUE(detector.ok()) << detector.error().message;
  const DetectResult result = (*detector)->detectFrame(wideImage(), "cam0", 42);
  ASSERT_TRUE(result.refusal.has_value());
  EXPECT_EQ(result.refusal->reason, DetectFailure::kModelOutputMismatch);
  EXPECT_STREQ(detectFailureName(result.refusal->reason), "model_output_mismatch");
  EXPECT_TRUE(result.detections.empty());
}

TEST(DnnDetector, AClassIdWithoutANameIsAnError) {
  SKIP_WITHOUT_ONNX(python);
  TempDir dir;
  const fs::path model = makeTinyDetector(*python, dir.path(), "ssd", 32, 32, {"0,3,0.9,0.1,0.1,0.2,0.2"});
  ASSERT_FALSE(model.empty());
  writeFile(dir.path() / "names.txt", "person\ncar\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(model, dir.path() / "names.txt", DnnOutput::kSsd);
  const auto detections = detectWith(config, wideImage());
  ASSERT_FALSE(detections.ok());
  EXPECT_NE(detections.error().message.find("class id 3"), std::string::npos) << detections.error().message;
  auto detector = makeDetector(config);
  ASSERT_TRUE(detector.ok()) << detector.error().message;
  const DetectResult result = (*detector)->detectFrame(wideImage(), "cam0", 42);
  ASSERT_TRUE(result.refusal.has_value());
  EXPECT_EQ(result.refusal->reason, DetectFailure::kModelOutputMismatch);
}

TEST(DnnDetector, AModelOpenCvCannotReadIsAnErrorNamingTheFile) {
  TempDir dir;
  writeFile(dir.path() / "broken.onnx", "this is not a protobuf");
  writeFile(dir.path() / "names.txt", "person\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(dir.path() / "broken.onnx", dir.path() / "names.txt", DnnOutput::kSsd);
  const auto detector = makeDetector(config);
  ASSERT_FALSE(detector.ok());
  EXPECT_NE(detector.error().message.find("dnn.model_path"), std::string::npos) << detector.error().message;
  EXPECT_NE(detector.error().message.find("broken.onnx"), std::string::npos) << detector.error().message;
}

// ---- Config -----------------------------------------------------------------------------------

TEST(DetectorConfig, AnUnknownKindOrOutputIsRefusedNamingTheField) {
  EXPECT_EQ(*parseDetectorKind("dnn"), DetectorKind::kDnn);
  const auto kind = parseDetectorKind("sift");
  ASSERT_FALSE(kind.ok());
  EXPECT_EQ(kind.error().message.rfind("kind:", 0), 0u) << kind.error().message;
  EXPECT_NE(kind.error().message.find("sift"), std::string::npos);
  EXPECT_EQ(*parseDnnOutput("yolo-export"), DnnOutput::kYoloExport);
  const auto output = parseDnnOutput("retinanet");
  ASSERT_FALSE(output.ok());
  EXPECT_NE(output.error().message.find("dnn.output"), std::string::npos) << output.error().message;
}

TEST(DetectorConfig, AMissingModelFileIsNotFoundNamingTheFieldAndPath) {
  TempDir dir;
  writeFile(dir.path() / "names.txt", "person\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(dir.path() / "absent.onnx", dir.path() / "names.txt", DnnOutput::kSsd);
  const Status status = validate(config);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, ErrorCode::kNotFound);
  EXPECT_NE(status.error().message.find("dnn.model_path"), std::string::npos) << status.error().message;
  EXPECT_NE(status.error().message.find("absent.onnx"), std::string::npos) << status.error().message;

  config.dnn.model_path.clear();
  ASSERT_FALSE(validate(config).ok());
  EXPECT_NE(validate(config).error().message.find("dnn.model_path: is required"), std::string::npos);
}

TEST(DetectorConfig, AnEmptyNamesFileIsRefusedNamingTheField) {
  TempDir dir;
  writeFile(dir.path() / "model.onnx", "never read: the names fail first");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(dir.path() / "model.onnx", dir.path() / "names.txt", DnnOutput::kSsd);
  for (const std::string text : {"", "\n\n", "person\n\ncar\n"}) {
    SCOPED_TRACE("names file: '" + text + "'");
    writeFile(dir.path() / "names.txt", text);
    const auto detector = makeDetector(config);
    ASSERT_FALSE(detector.ok());
    EXPECT_NE(detector.error().message.find("dnn.names_path"), std::string::npos) << detector.error().message;
  }
  // Trailing blank lines and carriage returns are not names.
  writeFile(dir.path() / "names.txt", "person\r\ncar \r\n\n");
  const auto names = readClassNames((dir.path() / "names.txt").string());
  ASSERT_TRUE(names.ok()) << names.error().message;
  EXPECT_EQ(*names, (std::vector<std::string>{"person", "car"}));
}

TEST(DetectorConfig, ThresholdsOutsideTheUnitIntervalAreRefusedNamingTheField) {
  TempDir dir;
  writeFile(dir.path() / "model.onnx", "x");
  writeFile(dir.path() / "names.txt", "person\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(dir.path() / "model.onnx", dir.path() / "names.txt", DnnOutput::kSsd);
  ASSERT_TRUE(validate(config).ok()) << validate(config).error().message;
  for (double bad : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    DetectorConfig c = config;
    c.dnn.confidence_threshold = bad;
    ASSERT_FALSE(validate(c).ok());
    EXPECT_EQ(validate(c).error().message.rfind("dnn.confidence_threshold:", 0), 0u) << validate(c).error().message;
    c = config;
    c.dnn.nms_threshold = bad;
    ASSERT_FALSE(validate(c).ok());
    EXPECT_EQ(validate(c).error().message.rfind("dnn.nms_threshold:", 0), 0u) << validate(c).error().message;
  }
  DetectorConfig hog;
  hog.hog.nms_iou = 2.0;
  ASSERT_FALSE(validate(hog).ok());
  EXPECT_EQ(validate(hog).error().message.rfind("hog.nms_iou:", 0), 0u) << validate(hog).error().message;
}

TEST(DetectorConfig, ANetworkInputAboveTheBoundsIsRefusedNamingTheField) {
  TempDir dir;
  writeFile(dir.path() / "model.onnx", "x");
  writeFile(dir.path() / "names.txt", "person\n");
  DetectorConfig config;
  config.kind = DetectorKind::kDnn;
  config.dnn = tinyDnn(dir.path() / "model.onnx", dir.path() / "names.txt", DnnOutput::kSsd);
  const auto refusedFor = [&](int width, int height) -> std::string {
    DetectorConfig c = config;
    c.dnn.input_width = width;
    c.dnn.input_height = height;
    const Status s = validate(c);
    return s.ok() ? std::string() : s.error().message;
  };
  EXPECT_EQ(refusedFor(1280, 1280), "");
  EXPECT_EQ(refusedFor(kMaxDnnInputSidePx, 512), "");
  EXPECT_EQ(refusedFor(2048, 2048), "");
  EXPECT_EQ(refusedFor(100000, 100000).rfind("dnn.input_width:", 0), 0u) << refusedFor(100000, 100000);
  EXPECT_NE(refusedFor(100000, 100000).find("100000"), std::string::npos);
  EXPECT_EQ(refusedFor(640, 100000).rfind("dnn.input_height:", 0), 0u) << refusedFor(640, 100000);
  EXPECT_EQ(refusedFor(0, 300).rfind("dnn.input_width:", 0), 0u) << refusedFor(0, 300);
  // Each side within its bound, together above the product's.
  const std::string both = refusedFor(8192, 8192);
  EXPECT_EQ(both.rfind("dnn.input_width x dnn.input_height:", 0), 0u) << both;
  EXPECT_NE(both.find("67108864"), std::string::npos) << both;
  // makeDetector validates first: the model is never read for such an input.
  config.dnn.input_width = config.dnn.input_height = 100000;
  const auto detector = makeDetector(config);
  ASSERT_FALSE(detector.ok());
  EXPECT_NE(detector.error().message.find("dnn.input_width"), std::string::npos) << detector.error().message;
}

TEST(DetectorConfig, HogParametersOutOfRangeAreRefusedNamingTheField) {
  EXPECT_TRUE(validate(DetectorConfig{}).ok());
  const std::vector<std::pair<std::string, void (*)(HogConfig&)>> cases{
      {"hog.scale", [](HogConfig& c) { c.scale = 1.0; }},
      {"hog.win_stride_px", [](HogConfig& c) { c.win_stride_px = 6; }},
      {"hog.upscale", [](HogConfig& c) { c.upscale = 0.5; }},
      {"hog.min_height_px", [](HogConfig& c) { c.min_height_px = -1.0; }},
      {"hog.hit_threshold", [](HogConfig& c) { c.hit_threshold = std::numeric_limits<double>::infinity(); }},
  };
  for (const auto& [field, breakIt] : cases) {
    DetectorConfig config;
    breakIt(config.hog);
    const Status status = validate(config);
    ASSERT_FALSE(status.ok()) << field;
    EXPECT_EQ(status.error().message.rfind(field + ":", 0), 0u) << status.error().message;
  }
}

// ---- Frame queue ------------------------------------------------------------------------------

CameraFrame frameAt(std::int64_t time_ns) { return {cv::Mat(2, 2, CV_8UC3, cv::Scalar(0)), "cam0", time_ns}; }

TEST(FrameQueue, OverflowDropsTheOldestFramesAndCountsThem) {
  FrameQueue queue(FrameQueueConfig{2});
  for (std::int64_t t = 1; t <= 5; ++t) EXPECT_TRUE(queue.push(frameAt(t)));
  EXPECT_EQ(queue.size(), 2u);
  EXPECT_EQ(queue.dropped(), 3u);
  const auto first = queue.pop(std::chrono::milliseconds(0));
  const auto second = queue.pop(std::chrono::milliseconds(0));
  ASSERT_TRUE(first && second);
  EXPECT_EQ(first->capture_time_ns, 4);
  EXPECT_EQ(second->capture_time_ns, 5);
  EXPECT_FALSE(queue.pop(std::chrono::milliseconds(0)));  // empty: nothing, at once
}

TEST(FrameQueue, CloseWakesABlockedPop) {
  FrameQueue queue(FrameQueueConfig{2});
  std::latch popping(1);
  auto popped = std::async(std::launch::async, [&] {
    popping.count_down();
    // Far longer than the wait below: returning in time means close() woke it.
    return queue.pop(std::chrono::seconds(60));
  });
  popping.wait();
  queue.close();
  ASSERT_EQ(popped.wait_for(std::chrono::seconds(30)), std::future_status::ready) << "close() left pop() waiting";
  EXPECT_FALSE(popped.get());
}

TEST(FrameQueue, AClosedQueueRefusesPushesButDrainsWhatItHolds) {
  FrameQueue queue(FrameQueueConfig{3});
  ASSERT_TRUE(queue.push(frameAt(1)));
  queue.close();
  EXPECT_TRUE(queue.closed());
  EXPECT_FALSE(queue.push(frameAt(2)));
  const auto held = queue.pop(std::chrono::milliseconds(0));
  ASSERT_TRUE(held);
  EXPECT_EQ(held->capture_time_ns, 1);
  EXPECT_FALSE(queue.pop(std::chrono::minutes(2)));  // closed and empty: returns at once
}

TEST(FrameQueue, AReaderAndASlowerDetectorLoseOnlyCountedFramesInOrder) {
  constexpr std::int64_t kFrames = 2000;
  FrameQueue queue(FrameQueueConfig{4});
  std::vector<std::int64_t> seen;
  std::thread detector([&] {
    while (auto frame = queue.pop(std::chrono::seconds(60))) seen.push_back(frame->capture_time_ns);
  });
  for (std::int64_t t = 1; t <= kFrames; ++t) EXPECT_TRUE(queue.push(frameAt(t)));
  queue.close();
  detector.join();
  EXPECT_EQ(static_cast<std::uint64_t>(seen.size()) + queue.dropped(), static_cast<std::uint64_t>(kFrames));
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), kFrames);  // the newest frame is never the one dropped
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_LT(seen[i - 1], seen[i]);
}

TEST(FrameQueue, AZeroCapacityConfigIsRefused) {
  EXPECT_TRUE(validate(FrameQueueConfig{}).ok());
  const Status status = validate(FrameQueueConfig{0});
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("frame_queue.capacity"), std::string::npos);
}

}  // namespace
}  // namespace fogmap::camera
