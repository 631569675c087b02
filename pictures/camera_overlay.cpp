#include "pictures/camera_overlay.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <optional>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/camera/pinhole.hpp"
#include "common/geometry/object_shape.hpp"
#include "pictures/drawing.hpp"

namespace fogmap::pictures {
namespace {

using drawing::bgr;
using drawing::fixedPoint;

// Depth 0 .. 60 m from red (near) through yellow and green to blue (far).
cv::Scalar depthColour(double depth_m) {
  const double t = std::clamp(depth_m / 60.0, 0.0, 1.0);
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(static_cast<int>(t * 120.0), 255, 255));
  cv::Mat rgb;
  cv::cvtColor(hsv, rgb, cv::COLOR_HSV2BGR);
  const cv::Vec3b c = rgb.at<cv::Vec3b>(0, 0);
  return {static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2])};
}

// A box's 12 edges: bottom face 0-3, top face 4-7 (camera::boxCorners' order, and OrientedBox::corners').
constexpr std::array<std::array<int, 2>, 12> kEdges{{{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                                     {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}}};

// Draws the edges of a box whose corners (rectified camera frame) lie in front of the camera; returns
// the top left of the drawn corners' bounding rectangle (the place for its caption, as a label's
// is at its 2D box), or nothing when no edge is drawn.
std::optional<cv::Point> drawWireframe(cv::Mat& frame, const Eigen::Matrix<double, 3, 4>& projection,
                                       const std::array<Eigen::Vector3d, 8>& rectified, const cv::Scalar& colour) {
  std::array<std::optional<Eigen::Vector2d>, 8> px;
  for (std::size_t k = 0; k < 8; ++k) px[k] = camera::projectPoint(projection, rectified[k], 0.1);
  std::optional<cv::Point> top;
  for (const auto& [a, b] : kEdges) {
    const auto& pa = px[static_cast<std::size_t>(a)];
    const auto& pb = px[static_cast<std::size_t>(b)];
    if (!pa || !pb) continue;
    cv::line(frame, drawing::fixedPoint(*pa), drawing::fixedPoint(*pb), colour, 2, cv::LINE_AA, drawing::kShift);
    for (const auto& p : {*pa, *pb}) {
      const cv::Point at(static_cast<int>(p.x()), static_cast<int>(p.y()));
      top = top ? cv::Point(std::min(top->x, at.x), std::min(top->y, at.y)) : at;
    }
  }
  return top;
}

const Rgb kBoxColour{0, 200, 70};
const Rgb kDetectionColour{230, 30, 30};
const Rgb kObjectColour{0, 190, 255};

}  // namespace

Expected<OverlayCounts> writeCameraOverlay(const std::filesystem::path& image, const camera::KittiCalibration& calibration,
                                           const OverlayLayers& layers, const std::filesystem::path& out) {
  cv::Mat frame = cv::imread(image.string(), cv::IMREAD_COLOR);
  if (frame.empty()) return ioError("overlay: cannot read the image " + image.string());
  const auto& p2 = calibration.projection[2];
  OverlayCounts counts;

  for (const Point& point : layers.lidar_points) {
    const Eigen::Vector3d rect = calibration.velodyneToRectified(Eigen::Vector3d(point.x, point.y, point.z));
    const auto pixel = camera::projectPoint(p2, rect, 1.0);
    if (!pixel || pixel->x() < 0 || pixel->y() < 0 || pixel->x() >= frame.cols || pixel->y() >= frame.rows) continue;
    cv::circle(frame, fixedPoint(*pixel), drawing::fixedLength(1.5), depthColour(rect.z()), cv::FILLED, cv::LINE_AA,
               drawing::kShift);
    ++counts.points_drawn;
  }

  const drawing::Pen pen{0.5, 1};
  for (const auto& label : layers.labels) {
    if (label.type == "DontCare") continue;
    if (!drawWireframe(frame, p2, camera::boxCorners(label), bgr(kBoxColour))) continue;
    ++counts.boxes_drawn;
    pen.writeOnMap(frame, label.type, cv::Point(static_cast<int>(label.box.left), std::max(12, static_cast<int>(label.box.top) - 4)),
                   bgr(kBoxColour));
  }

  std::array<std::size_t, kObjectClassCount + 1> boxes_by_class{};  // the last: no class
  if (!layers.objects.empty()) {
    const auto cam = camera::pinholeCamera(calibration, 2, frame.cols, frame.rows);
    if (!cam) return Error{cam.error().code, "overlay: " + cam.error().message};
    for (const MapObject& object : layers.objects) {
      // An object with an oriented box: its wireframe in its class's colour, captioned.
      if (const auto oriented = objectBox(object)) {
        const auto label = objectLabel(object);
        std::array<Eigen::Vector3d, 8> rectified;
        const auto corners = oriented->corners();
        for (std::size_t k = 0; k < 8; ++k) rectified[k] = calibration.velodyneToRectified(corners[k]);
        const cv::Scalar colour = bgr(label ? birdseyeClassColour(label->object_class) : kObjectColour);
        const auto top = drawWireframe(frame, p2, rectified, colour);
        if (!top) continue;
        char caption[48];
        if (label) {
          std::snprintf(caption, sizeof caption, "%s %.2f", std::string(objectClassName(label->object_class)).c_str(), label->confidence);
        } else {
          std::snprintf(caption, sizeof caption, "no class");
        }
        pen.writeOnMap(frame, caption, cv::Point(top->x, std::max(12, top->y - 4)), colour);
        ++counts.objects_drawn;
        ++counts.object_boxes_drawn;
        ++boxes_by_class[label ? static_cast<std::size_t>(label->object_class) : kObjectClassCount];
        continue;
      }
      std::optional<camera::Box2d> box;
      for (const Ellipsoid& e : object.ellipsoids) {
        const auto b = camera::projectEllipsoid(*cam, e.center, e.shape, 1.0);
        if (!b) continue;
        if (!box) box = *b;
        box->left = std::min(box->left, b->left);
        box->top = std::min(box->top, b->top);
        box->right = std::max(box->right, b->right);
        box->bottom = std::max(box->bottom, b->bottom);
      }
      if (!box || box->right < 0 || box->bottom < 0 || box->left >= frame.cols || box->top >= frame.rows) continue;
      cv::rectangle(frame, fixedPoint({box->left, box->top}), fixedPoint({box->right, box->bottom}), bgr(kObjectColour), 1, cv::LINE_AA,
                    drawing::kShift);
      ++counts.objects_drawn;
    }
  }

  for (const auto& d : layers.detections) {
    cv::rectangle(frame, cv::Point(static_cast<int>(d.box.left), static_cast<int>(d.box.top)),
                  cv::Point(static_cast<int>(d.box.right), static_cast<int>(d.box.bottom)), bgr(kDetectionColour), 2, cv::LINE_AA);
    char text[96];
    std::snprintf(text, sizeof text, "%s %.2f", d.label.c_str(), d.score);
    pen.writeOnMap(frame, text, cv::Point(static_cast<int>(d.box.left), static_cast<int>(d.box.bottom) + 14), bgr(kDetectionColour));
    ++counts.detections_drawn;
  }

  // The legend, top left, on a white panel: a row per layer given.
  std::vector<std::pair<std::string, cv::Scalar>> rows;
  if (!layers.lidar_points.empty()) {
    rows.emplace_back("LiDAR points: " + std::to_string(counts.points_drawn) + ", red near .. blue 60 m", depthColour(10.0));
  }
  if (!layers.labels.empty()) rows.emplace_back("labelled 3D boxes, projected: " + std::to_string(counts.boxes_drawn), bgr(kBoxColour));
  if (!layers.detections.empty()) rows.emplace_back("2D detections: " + std::to_string(counts.detections_drawn), bgr(kDetectionColour));
  if (!layers.objects.empty()) {
    // One row per class drawn: its colour and how many boxes.
    for (std::size_t k = 0; k <= kObjectClassCount; ++k) {
      if (boxes_by_class[k] == 0) continue;
      const bool classed = k < kObjectClassCount;
      const std::string name = classed ? std::string(objectClassName(static_cast<ObjectClass>(k))) : std::string("no class");
      rows.emplace_back("map objects' oriented boxes, LiDAR class " + name + ": " + std::to_string(boxes_by_class[k]),
                        bgr(classed ? birdseyeClassColour(static_cast<ObjectClass>(k)) : kObjectColour));
    }
    if (counts.objects_drawn > counts.object_boxes_drawn || counts.objects_drawn == 0) {
      rows.emplace_back("map objects: the box of each one's ellipsoids projected, " +
                            std::to_string(counts.objects_drawn - counts.object_boxes_drawn),
                        bgr(kObjectColour));
    }
  }
  int width = 0;
  for (const auto& [text, colour] : rows) width = std::max(width, pen.size(text).width);
  if (!rows.empty()) {
    cv::rectangle(frame, cv::Point(4, 4), cv::Point(4 + width + 34, 4 + 20 * static_cast<int>(rows.size()) + 8),
                  cv::Scalar(255, 255, 255), cv::FILLED);
  }
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const int y = 24 + 20 * static_cast<int>(r);
    cv::rectangle(frame, cv::Point(10, y - 10), cv::Point(26, y), rows[r].second, cv::FILLED);
    pen.write(frame, rows[r].first, cv::Point(32, y), cv::Scalar(20, 20, 20));
  }
  if (Status s = drawing::writePng(out, frame, "overlay"); !s) return s.error();
  return counts;
}

}  // namespace fogmap::pictures
