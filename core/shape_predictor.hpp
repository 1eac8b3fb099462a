// Landmark prediction by an Ensemble of Regression Trees (Kazemi & Sullivan, "One
// Millisecond Face Alignment with an Ensemble of Regression Trees", CVPR 2014), evaluated
// over the data of a dlib shape predictor (.dat) without allocating per frame.
//
// dlib::shape_predictor::operator() allocates on every call (the result's vector, the
// feature pixel vector, the similarity fit's point lists), which the live pipeline must
// not do. ShapePredictorData holds the same trees in flat arrays; ShapePredictor owns the
// per-call scratch. The arithmetic follows dlib's step for step (float shape, double
// similarity transform, nearest-pixel lookup, 0 outside the image), so the same pixels are
// read, the same leaves are chosen and the landmarks agree with dlib's to float precision;
// unlike dlib's rounded `point`s, the result keeps the sub-pixel position.
#pragma once

#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <istream>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

namespace lipdrive {

/// A face box in image pixels with inclusive corners, the convention of dlib::rectangle
/// (a 100 px wide box has right = left + 99).
struct FaceBox {
  long left = 0, top = 0, right = -1, bottom = -1;

  long width() const { return right - left + 1; }
  long height() const { return bottom - top + 1; }
  bool empty() const { return right < left || bottom < top; }
};

/// The stream does not hold a dlib shape predictor, or one lipdrive cannot use.
class ShapePredictorFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The trees of a trained predictor, immutable once read: share one instance (the Debian
/// 68-point model is ~95 MB) between every tracker through a shared_ptr<const ...>.
class ShapePredictorData {
 public:
  /// Reads the fields of a serialized dlib::shape_predictor in the order dlib's
  /// deserialize(shape_predictor&, istream&) reads them, with dlib's own deserializers.
  /// Throws ShapePredictorFormatError when the stream is not a shape predictor, its trees
  /// are not complete binary trees of one depth, or it does not predict 68 landmarks.
  static ShapePredictorData read_dlib(std::istream& in);

  int num_cascades() const { return static_cast<int>(cascade_first_tree_.size()) - 1; }
  int num_trees() const { return cascade_first_tree_.back(); }
  int tree_depth() const { return tree_depth_; }
  /// Feature pixels of the largest cascade: the size of a ShapePredictor's scratch.
  int max_features_per_cascade() const { return max_features_; }

  /// The box in which the predictor's mean shape best matches `landmarks` (least squares
  /// over scale and translation; rigid landmarks 17..47 only, so speech does not move it):
  /// how a tracker turns the last frame's landmarks into this frame's box, consistent
  /// with the detector boxes the predictor was trained on.
  FaceBox box_for(const Landmarks2D& landmarks) const;

 private:
  friend class ShapePredictor;
  ShapePredictorData() = default;

  static constexpr int kShapeSize = 2 * kNumLandmarks;  // x0,y0,x1,y1,... in box units [0,1]

  int tree_depth_ = 0;  // splits per tree = 2^depth - 1, leaves = 2^depth
  int max_features_ = 0;
  std::vector<float> initial_shape_;        // kShapeSize: the mean shape, box-normalised
  std::vector<int> cascade_first_tree_;     // cascades + 1 offsets into the tree arrays
  std::vector<int> cascade_first_feature_;  // cascades + 1 offsets into anchor/delta arrays
  std::vector<std::uint16_t> anchor_;       // landmark each feature pixel is attached to
  std::vector<float> delta_;                // 2 per feature: offset from its anchor in the mean shape
  struct Split {                            // go to the left child when pixel[first] - pixel[second] > threshold
    std::uint16_t first, second;
    float threshold;
  };
  std::vector<Split> splits_;       // breadth-first within a tree, tree after tree
  std::vector<float> leaf_values_;  // per leaf: kShapeSize shape increments
};

/// Evaluates shared predictor data with its own scratch; one per thread.
class ShapePredictor {
 public:
  explicit ShapePredictor(std::shared_ptr<const ShapePredictorData> data);

  /// The 68 landmarks in image pixels for a face in `box` of the 8-bit luma image `gray`
  /// (CV_8UC1, any stride). Allocates nothing.
  void predict(const cv::Mat& gray, const FaceBox& box, Landmarks2D& out);

  /// Standard deviation of the last cascade's feature pixel intensities in the last
  /// predict(): near 0 when the box holds no texture at all (a blank or covered frame).
  float feature_contrast() const;

  /// The leaf chosen in each tree by the last predict(), tree after tree: lets a test
  /// check that every decision agrees with dlib's.
  std::span<const std::uint8_t> last_leaves() const { return leaves_; }

  const std::shared_ptr<const ShapePredictorData>& data() const { return data_; }

 private:
  void read_feature_pixels(const cv::Mat& gray, const FaceBox& box, int cascade);

  std::shared_ptr<const ShapePredictorData> data_;
  std::vector<float> shape_;           // current shape estimate, box-normalised
  std::vector<float> feature_pixels_;  // intensities of the current cascade's feature pixels
  std::vector<std::uint8_t> leaves_;
};

}  // namespace lipdrive
