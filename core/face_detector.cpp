#include "core/face_detector.hpp"

#include <dlib/image_processing/frontal_face_detector.h>
#include <dlib/opencv/cv_image.h>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace lipdrive {

struct FaceDetector::Hog {
  dlib::frontal_face_detector detector;
};

FaceDetector::FaceDetector(std::unique_ptr<Hog> hog) : hog_(std::move(hog)) {}
FaceDetector::FaceDetector(const FaceDetector& other) : hog_(std::make_unique<Hog>(*other.hog_)) {}
FaceDetector& FaceDetector::operator=(const FaceDetector& other) {
  if (this != &other) hog_ = std::make_unique<Hog>(*other.hog_);
  return *this;
}
FaceDetector::FaceDetector(FaceDetector&&) noexcept = default;
FaceDetector& FaceDetector::operator=(FaceDetector&&) noexcept = default;
FaceDetector::~FaceDetector() = default;

FaceDetector FaceDetector::builtin() {
  return FaceDetector(std::make_unique<Hog>(Hog{dlib::get_frontal_face_detector()}));
}

FaceDetector FaceDetector::deserialize(std::span<const std::uint8_t> bytes) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  auto hog = std::make_unique<Hog>();
  try {
    dlib::deserialize(hog->detector, in);
  } catch (const std::exception& e) {
    // dlib::serialization_error, or bad_alloc/length_error from a garbage size.
    throw std::runtime_error(std::string("not a dlib frontal face detector: ") + e.what());
  }
  if (hog->detector.num_detectors() == 0) throw std::runtime_error("not a dlib frontal face detector: no detectors");
  return FaceDetector(std::move(hog));
}

std::vector<std::uint8_t> FaceDetector::serialize() const {
  std::ostringstream out;
  dlib::serialize(hog_->detector, out);
  const std::string bytes = out.str();
  return {bytes.begin(), bytes.end()};
}

namespace {

/// dlib's built-in detector is five HOG filters: a face looking to the front, to the left, to
/// the right, to the front rolled one way and to the front rolled the other
/// (dlib/image_processing/frontal_face_detector.h). Its last two find faces rolled by about
/// 10-40 and 20-50 degrees (GRID frames turned in steps of 10 degrees; the front filter
/// finds them to 10): their boxes are turned by about the middle of that.
constexpr unsigned long kBuiltinFilters = 5, kRolledFilter = 3, kRolledOtherWayFilter = 4;
constexpr double kRolledFilterRoll = -30 * std::numbers::pi / 180;

/// `boxes` largest first (the same size: in the detector's order).
std::vector<FaceBox> largest_first(std::vector<FaceBox> boxes) {
  std::stable_sort(boxes.begin(), boxes.end(), [](const FaceBox& a, const FaceBox& b) { return a.area() > b.area(); });
  return boxes;
}

}  // namespace

std::vector<FaceBox> FaceDetector::detect(const cv::Mat& gray) {
  std::vector<FaceBox> boxes;
  std::vector<dlib::rect_detection> found;
  hog_->detector(dlib::cv_image<unsigned char>(gray), found);
  const bool builtin = hog_->detector.num_detectors() == kBuiltinFilters;
  for (const dlib::rect_detection& d : found) {
    const dlib::rectangle& r = d.rect;
    const double roll = !builtin                                  ? 0
                        : d.weight_index == kRolledFilter         ? kRolledFilterRoll
                        : d.weight_index == kRolledOtherWayFilter ? -kRolledFilterRoll
                                                                  : 0;
    boxes.push_back({r.left(), r.top(), r.right(), r.bottom(), roll});
  }
  return largest_first(std::move(boxes));
}

struct CascadeFaceDetector::Cascades {
  cv::CascadeClassifier face, eye;
  cv::Mat equalised;  // scratch
};

namespace {

/// The cascade in `xml`, the text of an OpenCV cascade file; `what` names it in the error.
void read_cascade(const std::string& xml, cv::CascadeClassifier& cascade, const char* what) {
  bool read = false;
  try {
    const cv::FileStorage storage(xml, cv::FileStorage::READ | cv::FileStorage::MEMORY);
    // A cascade file holds one top-level node, the cascade (OpenCV's own loader reads it so).
    read = storage.isOpened() && cascade.read(storage.getFirstTopLevelNode());
  } catch (const cv::Exception& e) {
    throw std::runtime_error(std::string("not an OpenCV ") + what + " cascade: " + e.what());
  }
  if (!read || cascade.empty()) throw std::runtime_error(std::string("not an OpenCV ") + what + " cascade");
}

}  // namespace

CascadeFaceDetector::CascadeFaceDetector(std::shared_ptr<const std::string> face_xml,
                                         std::shared_ptr<const std::string> eye_xml)
    : face_xml_(std::move(face_xml)), eye_xml_(std::move(eye_xml)), cascades_(std::make_unique<Cascades>()) {
  read_cascade(*face_xml_, cascades_->face, "face");
  read_cascade(*eye_xml_, cascades_->eye, "eye");
}

CascadeFaceDetector::CascadeFaceDetector(const CascadeFaceDetector& other)
    : CascadeFaceDetector(other.face_xml_, other.eye_xml_) {}
CascadeFaceDetector::~CascadeFaceDetector() = default;

namespace {

/// Where dlib's detector puts the box of a face the cascade finds (measured on the frames at
/// 1.2 s of the first 40 clips of GRID's grid_train, where both find one face: dlib's box is
/// 0.86 times as wide, standard deviation 0.07, with its centre 0.10 of the cascade's width
/// lower, deviation 0.03, and none across). The landmark prediction from seven boxes around it
/// (ShapePredictor::predict_median) takes up the rest.
constexpr double kCascadeToHogWidth = 0.86, kCascadeToHogDown = 0.10;
/// A face must gather more than this many overlapping detections (at neighbouring positions
/// and scales; OpenCV's minNeighbors). OpenCV's default, 3, passes a rock, a hand and a
/// diagram as faces: on 65 cut-outs of photographs around their faces and 24 drawings, the
/// cascade's false detections gathered 2 to 5; the faces it finds that dlib's detector misses
/// 8 and more (the test's face half in shadow 8 to 10, a poster lit from one side 16), GRID's
/// faces from 48 pixels wide 13 to 75. Clouds of blurred noise gather up to 13: sees_an_eye
/// tells them apart.
constexpr int kMinNeighbours = 6;
/// The eye cascade's boxes searched for, over the inter-ocular distance, and how far from
/// where the landmarks put the eye one may lie.
constexpr double kEyeSmallest = 0.2, kEyeLargest = 0.8, kEyeWithin = 0.25;
/// The eye cascade's window (haarcascade_eye.xml): the smallest eye it finds, in pixels.
constexpr int kEyeWindowPx = 20;

}  // namespace

std::vector<FaceBox> CascadeFaceDetector::detect(const cv::Mat& gray, double min_width) {
  cv::equalizeHist(gray, cascades_->equalised);
  std::vector<cv::Rect> found;
  const int min_size = static_cast<int>(std::ceil(min_width));
  cascades_->face.detectMultiScale(cascades_->equalised, found, 1.1, kMinNeighbours, 0, {min_size, min_size});
  std::vector<FaceBox> boxes;
  for (const cv::Rect& r : found) {
    const double half = 0.5 * kCascadeToHogWidth * r.width;
    const double x = r.x + 0.5 * r.width, y = r.y + 0.5 * r.height + kCascadeToHogDown * r.width;
    boxes.push_back(
        {std::lround(x - half), std::lround(y - half), std::lround(x + half) - 1, std::lround(y + half) - 1});
  }
  return largest_first(std::move(boxes));
}

bool CascadeFaceDetector::sees_an_eye(const cv::Mat& gray, const Landmarks2D& landmarks) {
  const double iod = interocular_distance(landmarks);
  const cv::Rect picture(0, 0, gray.cols, gray.rows);
  for (const auto [outer, inner] :
       {std::pair(ibug::kRightEyeOuter, ibug::kRightEyeInner), std::pair(ibug::kLeftEyeInner, ibug::kLeftEyeOuter)}) {
    const Eigen::Vector2d eye = 0.5 * (landmarks.col(outer) + landmarks.col(inner));
    // The eye cascade's window holds the eye and its lid, about 0.3-0.5 inter-ocular
    // distances wide; its surroundings, one inter-ocular distance square.
    const int side = static_cast<int>(std::lround(iod));
    const cv::Rect around = cv::Rect(static_cast<int>(std::lround(eye.x())) - side / 2,
                                     static_cast<int>(std::lround(eye.y())) - side / 2, side, side) &
                            picture;
    if (around.width < kEyeWindowPx || around.height < kEyeWindowPx) continue;
    cv::equalizeHist(gray(around), cascades_->equalised);
    std::vector<cv::Rect> found;
    const int smallest = std::max(kEyeWindowPx, static_cast<int>(kEyeSmallest * iod));
    const int largest = std::max(smallest, static_cast<int>(kEyeLargest * iod));
    cascades_->eye.detectMultiScale(cascades_->equalised, found, 1.1, 3, 0, {smallest, smallest}, {largest, largest});
    for (const cv::Rect& r : found) {
      const Eigen::Vector2d centre(around.x + r.x + 0.5 * r.width, around.y + r.y + 0.5 * r.height);
      if ((centre - eye).norm() <= kEyeWithin * iod) return true;
    }
  }
  return false;
}

}  // namespace lipdrive
