// Landmark prediction by an Ensemble of Regression Trees (Kazemi & Sullivan, "One
// Millisecond Face Alignment with an Ensemble of Regression Trees", CVPR 2014), evaluated
// over the data of a dlib shape predictor without allocating per frame.
//
// dlib::shape_predictor::operator() allocates on every call (the result's vector, the
// feature pixel vector, the similarity fit's point lists), which the live pipeline must
// not do. ShapePredictorData holds the same trees in flat arrays; ShapePredictor owns the
// per-call scratch. The arithmetic follows dlib's step for step (float shape, double
// similarity transform, nearest-pixel lookup, 0 outside the image), so the same pixels are
// read and the same leaves are chosen; unlike dlib's rounded `point`s, the result keeps the
// sub-pixel position. The one difference is the leaf increments: each leaf's 136 values are
// stored as 24-bit integers with one f32 scale per leaf (Leaf below), 412 bytes instead of 544,
// which takes the 65 MB of leaves every frame reads from to 49 MB. A value moves by at most
// half a step, 2^-24 of its leaf's largest value; a feature pixel that lay within that of a
// pixel boundary is read one pixel over now and then, so 99.97 % of the trees choose dlib's
// leaf on the LFPW photographs and the landmarks differ from dlib's by 4e-5 inter-ocular
// distances on average (tests/test_face_tracker.cpp holds both to their bounds; 16-bit leaves
// moved the shape by ~0.005 px, 4 % of the trees then chose another leaf, 0.004 inter-ocular
// distances).
//
// Two sources: dlib's own .dat serialization (read_dlib, seconds: ~95 MB of small objects),
// and lipdrive's compact .lpp file (read_compact: the arrays as they are used, mapped from
// the file, with the face detector the predictor was trained with; milliseconds). Layout of
// the .lpp, version 2 (version 1 had f32 leaves); integers and floats little-endian
// (IEEE-754 binary32):
//
//   offset  size  field
//        0     8  magic "LPDPRED" + NUL
//        8     4  u32 format version = 2
//       12     4  u32 landmarks = 68
//       16     4  u32 tree depth D (1..8): 2^D - 1 splits and 2^D leaves per tree
//       20     4  u32 cascades C
//       24     4  u32 trees T, all cascades
//       28     4  u32 feature pixels F, all cascades
//       32     8  u64 face detector bytes B
//       40     8  u64 payload length (the bytes after this 64-byte header)
//       48     4  u32 CRC-32 of the payload (core/checksum.hpp)
//       52    12  reserved, zero
//       64        payload, each array starting at a multiple of 64 bytes from the file's start:
//                   f32[136]               mean shape, box-normalised (x0, y0, x1, ...)
//                   i32[C + 1]             first tree of each cascade, then T
//                   i32[C + 1]             first feature pixel of each cascade, then F
//                   u16[F]                 landmark each feature pixel is anchored to
//                   f32[2F]                its offset from the anchor in the mean shape
//                   {u16, u16, f32}[T (2^D - 1)]  splits, breadth first within a tree: go to
//                                          the left child when pixel[a] - pixel[b] > threshold
//                   {f32, i16[136], u8[136]}[T 2^D]  leaves, leaf after leaf, tree after tree:
//                                          increment k = (256 high[k] + low[k]) * scale
//                   u8[B]                  the face detector, dlib's serialization
//
// The file ends at the end of the payload.
#pragma once

#include "core/face_detector.hpp"
#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>

#include <array>
#include <cstdint>
#include <istream>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

namespace lipdrive {

/// The bytes do not hold a shape predictor lipdrive can use (.dat or .lpp).
class ShapePredictorFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The trees of a trained predictor and the face detector it was trained with, immutable once
/// read: share one instance between every tracker through a shared_ptr<const ...>.
class ShapePredictorData {
 public:
  /// Reads the fields of a serialized dlib::shape_predictor in the order dlib's
  /// deserialize(shape_predictor&, istream&) reads them, with dlib's number decoders; every
  /// count is checked against the bytes left before anything is allocated, so `in` must be
  /// seekable (a file or a string). A .dat holds no detector: `detector` makes the one the
  /// predictor was trained with (dlib's 68-point models: FaceDetector::builtin), called once
  /// the predictor has been read. Throws ShapePredictorFormatError when the stream is not a
  /// shape predictor (a count it cannot hold included), its trees are not complete binary
  /// trees of one depth, or it does not predict 68 landmarks.
  static ShapePredictorData read_dlib(std::istream& in, FaceDetector (*detector)());

  /// Whether `bytes` start like an .lpp file (its magic).
  static bool is_compact(std::span<const std::uint8_t> bytes);
  /// Uses the .lpp file in `bytes` in place: the result points into them, and keeps `owner`
  /// (whatever holds the bytes, e.g. a mapping of the file) alive as long as it lives. Every
  /// count, offset and index is checked before use. Throws ShapePredictorFormatError naming
  /// what is wrong.
  static ShapePredictorData read_compact(std::span<const std::uint8_t> bytes, std::shared_ptr<const void> owner);
  /// The .lpp file of this predictor.
  std::vector<std::uint8_t> write_compact() const;

  int num_cascades() const { return static_cast<int>(cascade_first_tree_.size()) - 1; }
  int num_trees() const { return cascade_first_tree_.back(); }
  int tree_depth() const { return tree_depth_; }
  /// Feature pixels of the largest cascade: the size of a ShapePredictor's scratch.
  int max_features_per_cascade() const { return max_features_; }

  /// The detector whose boxes the predictor was trained on; a tracker works on its own copy.
  const FaceDetector& detector() const { return detector_; }

  /// The box in which the predictor's mean shape best matches `landmarks` (least squares
  /// over scale and translation; rigid landmarks 17..47 only, so speech does not move it):
  /// how a tracker turns the last frame's landmarks into this frame's box, consistent
  /// with the detector boxes the predictor was trained on. The box is turned by the face's
  /// roll (the turn of the least-squares similarity) less `upright` radians towards zero: a
  /// face rolled by up to `upright` gets an upright box, as from the detector.
  FaceBox box_for(const Landmarks2D& landmarks, double upright = 0) const;

  static constexpr int kShapeSize = 2 * kNumLandmarks;  // x0,y0,x1,y1,... in box units [0,1]

  struct Split {  // go to the left child when pixel[first] - pixel[second] > threshold
    std::uint16_t first, second;
    float threshold;
  };

  /// One leaf's shape increments as 24-bit integers, split into a high and a low part so that
  /// 16 of them widen to floats in a few vector instructions: increment k =
  /// (256 high[k] + low[k]) * scale, scale = the largest |increment| / (2^23 - 1).
  struct Leaf {
    float scale;
    std::int16_t high[kShapeSize];
    std::uint8_t low[kShapeSize];

    float increment(int k) const { return static_cast<float>(256 * high[k] + low[k]) * scale; }
  };

 private:
  friend class ShapePredictor;
  explicit ShapePredictorData(FaceDetector detector) : detector_(std::move(detector)) {}

  int tree_depth_ = 0;  // splits per tree = 2^depth - 1, leaves = 2^depth
  int max_features_ = 0;
  // Views of the arrays of the .lpp layout above, in `storage_`.
  std::span<const float> initial_shape_;                 // kShapeSize: the mean shape
  std::span<const std::int32_t> cascade_first_tree_;     // cascades + 1 offsets into the tree arrays
  std::span<const std::int32_t> cascade_first_feature_;  // cascades + 1 offsets into anchor/delta arrays
  std::span<const std::uint16_t> anchor_;                // landmark each feature pixel is attached to
  std::span<const float> delta_;                         // 2 per feature: offset from its anchor
  std::span<const Split> splits_;                        // breadth-first within a tree, tree after tree
  std::span<const Leaf> leaf_increments_;                // 2^depth leaves per tree, tree after tree
  std::shared_ptr<const void> storage_;                  // the mapped file, or the arrays read_dlib built
  FaceDetector detector_;
};

/// Evaluates shared predictor data with its own scratch; one per thread.
/// What a feature pixel beyond the picture's edge reads: 0, as dlib reads it (and the
/// predictor was trained with), or the picture mirrored at its edge (as
/// cv::BORDER_REFLECT_101 pads it; 0 beyond the mirrored picture too).
enum class BeyondTheEdge { kBlack, kMirrored };

class ShapePredictor {
 public:
  explicit ShapePredictor(std::shared_ptr<const ShapePredictorData> data);

  /// The 68 landmarks in image pixels for a face in `box` of the 8-bit luma image `gray`
  /// (CV_8UC1, any stride). Allocates nothing.
  void predict(const cv::Mat& gray, const FaceBox& box, Landmarks2D& out, BeyondTheEdge beyond = BeyondTheEdge::kBlack);

  /// The landmarks of a face whose box is only roughly placed (a detector's): per coordinate,
  /// the median of predict() from `box` and from six boxes around it (scaled by 1 -/+ 5 %,
  /// shifted by -/+ 3 % of its size across and down). A cascade started once can settle on a
  /// wrong shape (a half-open mouth on a wide-open one, the jaw on the neck); started from
  /// several initial shapes, the median drops it (Cao, Wei, Wen & Sun, "Face Alignment by
  /// Explicit Shape Regression", CVPR 2012: multiple initialisations, median of the results).
  /// Seven times predict()'s cost; `box` is predicted last, so feature_contrast() and
  /// last_leaves() are its. Allocates nothing.
  void predict_median(const cv::Mat& gray, const FaceBox& box, Landmarks2D& out);

  /// Reads what the next predict() will most likely read, so that it finds it in the cache: each
  /// tree's splits and the leaf it chose in the last predict(), and the feature pixels' anchors
  /// and offsets (about 4 MB for dlib's 68-point predictor). For the idle time before a frame
  /// is due (a camera's frames come 16 ms apart, long enough for other work to evict them).
  /// Allocates nothing.
  void warm() const;

  /// Standard deviation of the last cascade's feature pixel intensities in the last
  /// predict(): near 0 when the box holds no texture at all (a blank or covered frame).
  float feature_contrast() const;

  /// The leaf chosen in each tree by the last predict(), tree after tree: lets a test
  /// compare every decision with dlib's.
  std::span<const std::uint8_t> last_leaves() const { return leaves_; }

  const std::shared_ptr<const ShapePredictorData>& data() const { return data_; }

 private:
  void read_feature_pixels(const cv::Mat& gray, const FaceBox& box, int cascade, BeyondTheEdge beyond);
  /// The leaf the last walk of `tree` ended in (leaves_).
  const ShapePredictorData::Leaf& chosen_leaf(int tree) const;

  std::shared_ptr<const ShapePredictorData> data_;
  std::vector<float> shape_;           // current shape estimate, box-normalised
  std::vector<float> feature_pixels_;  // intensities of the current cascade's feature pixels
  std::vector<std::uint8_t> leaves_;
  static constexpr int kStarts = 7;          // predict_median's boxes
  std::array<Landmarks2D, kStarts> starts_;  // their predictions, `box` last
};

}  // namespace lipdrive
