#include "core/face_detector.hpp"

#include <dlib/image_processing/frontal_face_detector.h>
#include <dlib/opencv/cv_image.h>

#include <algorithm>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

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
  std::stable_sort(boxes.begin(), boxes.end(), [](const FaceBox& a, const FaceBox& b) { return a.area() > b.area(); });
  return boxes;
}

}  // namespace lipdrive
