// Face detection: dlib's HOG frontal face detector (Dalal & Triggs, "Histograms of Oriented
// Gradients for Human Detection", CVPR 2005: HOG features, a linear SVM, an image pyramid),
// the detector whose boxes dlib's 68-point landmark predictor was trained on.
//
// dlib ships the detector compressed inside its headers; decoding it takes about a second of
// CPU, so it is decoded once per predictor file (ShapePredictorData holds it), or read in a
// few milliseconds from the compact predictor file, which stores it decoded. Each tracker
// works on a copy of its own: detection keeps scratch inside the detector.
#pragma once

#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace lipdrive {

/// A face box in image pixels with inclusive corners, the convention of dlib::rectangle
/// (a 100 px wide box has right = left + 99), turned by `roll` radians about its centre (from
/// the image's x axis towards its y axis, so clockwise on the screen). The shape predictor
/// places its mean shape in a turned box as in an upright box of the picture turned back
/// (docs/method.md 1, "A rolled head").
struct FaceBox {
  long left = 0, top = 0, right = -1, bottom = -1;
  double roll = 0;

  long width() const { return right - left + 1; }
  long height() const { return bottom - top + 1; }
  long area() const { return empty() ? 0 : width() * height(); }
  bool empty() const { return right < left || bottom < top; }
};

class FaceDetector {
 public:
  /// dlib's built-in frontal face detector, decoded (about a second of CPU).
  static FaceDetector builtin();
  /// A detector from the bytes serialize() wrote. Throws std::runtime_error when they do not
  /// hold one.
  static FaceDetector deserialize(std::span<const std::uint8_t> bytes);
  /// dlib's serialization of the decoded detector.
  std::vector<std::uint8_t> serialize() const;

  FaceDetector(const FaceDetector& other);
  FaceDetector& operator=(const FaceDetector& other);
  FaceDetector(FaceDetector&&) noexcept;
  FaceDetector& operator=(FaceDetector&&) noexcept;
  ~FaceDetector();

  /// The faces in the luma image `gray` (CV_8UC1), largest first. A face the built-in
  /// detector finds with a filter for rolled faces has its box turned by about that roll (30
  /// degrees); the others are upright. Allocates (it runs only to acquire a face).
  std::vector<FaceBox> detect(const cv::Mat& gray);

 private:
  struct Hog;  // dlib::frontal_face_detector, kept out of this header
  explicit FaceDetector(std::unique_ptr<Hog> hog);
  std::unique_ptr<Hog> hog_;
};

/// A second detector for photographs in which dlib's finds no face: OpenCV's cascade of boosted
/// Haar-like features (Viola & Jones, "Rapid Object Detection using a Boosted Cascade of Simple
/// Features", CVPR 2001; the extended feature set of Lienhart & Maydt, ICIP 2002, in Debian's
/// opencv-data: haarcascade_frontalface_alt2.xml), run on the histogram-equalised image. It
/// finds a face half in shadow, which the HOG filters miss (docs/method.md 1, "A face the HOG
/// detector misses"). Its boxes are moved to the HOG detector's convention, which the landmark
/// predictor was trained on. It also takes cloud-like textures for faces, so a face it finds
/// counts only where its eye cascade (haarcascade_eye.xml) finds an eye where the landmarks put
/// one (sees_an_eye).
class CascadeFaceDetector {
 public:
  /// The face and the eye cascade in `face_xml` and `eye_xml`, the texts of OpenCV's cascade
  /// files. Throws std::runtime_error naming which holds none.
  CascadeFaceDetector(std::shared_ptr<const std::string> face_xml, std::shared_ptr<const std::string> eye_xml);
  /// A copy works on cascades of its own (detection keeps scratch inside them): it reads the
  /// texts again.
  CascadeFaceDetector(const CascadeFaceDetector& other);
  CascadeFaceDetector& operator=(const CascadeFaceDetector&) = delete;
  ~CascadeFaceDetector();

  /// The faces in the luma image `gray` (CV_8UC1) at least `min_width` pixels wide, as upright
  /// boxes where dlib's detector would put them, largest first. Allocates (it runs only on a
  /// still in which dlib's detector found nothing).
  std::vector<FaceBox> detect(const cv::Mat& gray, double min_width);

  /// Whether the eye cascade finds an eye within a quarter of the inter-ocular distance of
  /// where `landmarks` (in `gray`) put either eye, searching each eye's surroundings after
  /// equalising their histogram (so the eye in a face's shadowed half counts). Allocates.
  bool sees_an_eye(const cv::Mat& gray, const Landmarks2D& landmarks);

 private:
  struct Cascades;  // cv::CascadeClassifier for the face and the eye, kept out of this header
  std::shared_ptr<const std::string> face_xml_, eye_xml_;
  std::unique_ptr<Cascades> cascades_;
};

}  // namespace lipdrive
