#include "core/face_detector.hpp"

#include <dlib/image_processing/frontal_face_detector.h>
#include <dlib/opencv/cv_image.h>

#include <algorithm>
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

std::vector<FaceBox> FaceDetector::detect(const cv::Mat& gray) {
  std::vector<FaceBox> boxes;
  for (const dlib::rectangle& r : hog_->detector(dlib::cv_image<unsigned char>(gray)))
    boxes.push_back({r.left(), r.top(), r.right(), r.bottom()});
  std::stable_sort(boxes.begin(), boxes.end(), [](const FaceBox& a, const FaceBox& b) { return a.area() > b.area(); });
  return boxes;
}

}  // namespace lipdrive
