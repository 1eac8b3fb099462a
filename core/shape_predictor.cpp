#include "core/shape_predictor.hpp"

#include <dlib/image_processing/shape_predictor.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <string>

namespace lipdrive {
namespace {

constexpr int kMaxTreeDepth = 8;  // leaf indices are stored in 8 bits

struct DlibFields {
  dlib::matrix<float, 0, 1> initial_shape;
  std::vector<std::vector<dlib::impl::regression_tree>> forests;
  std::vector<std::vector<unsigned long>> anchor_idx;
  std::vector<std::vector<dlib::vector<float, 2>>> deltas;
};

// The order of dlib's deserialize(shape_predictor&, istream&) (shape_predictor.h).
DlibFields read_fields(std::istream& in) {
  DlibFields f;
  try {
    int version = 0;
    dlib::deserialize(version, in);
    if (version != 1)
      throw ShapePredictorFormatError("not a dlib shape predictor (version " + std::to_string(version) + ")");
    dlib::deserialize(f.initial_shape, in);
    dlib::deserialize(f.forests, in);
    dlib::deserialize(f.anchor_idx, in);
    dlib::deserialize(f.deltas, in);
  } catch (const ShapePredictorFormatError&) {
    throw;
  } catch (const std::exception& e) {
    // dlib::serialization_error, or bad_alloc/length_error from a garbage vector size.
    throw ShapePredictorFormatError(std::string("not a dlib shape predictor: ") + e.what());
  }
  return f;
}

void check_fields(const DlibFields& f) {
  const auto fail = [](const std::string& what) { throw ShapePredictorFormatError(what); };
  if (f.initial_shape.size() != 2 * kNumLandmarks)
    fail("predicts " + std::to_string(f.initial_shape.size() / 2) + " landmarks; lipdrive needs the " +
         std::to_string(kNumLandmarks) + " iBUG landmarks");
  if (f.forests.empty() || f.anchor_idx.size() != f.forests.size() || f.deltas.size() != f.forests.size())
    fail("inconsistent cascade count");
  const std::size_t splits = f.forests.front().empty() ? 0 : f.forests.front().front().splits.size();
  const int depth = static_cast<int>(std::log2(static_cast<double>(splits + 1)));
  if (splits == 0 || (std::size_t{1} << depth) != splits + 1 || depth > kMaxTreeDepth)
    fail("trees are not complete binary trees of depth 1.." + std::to_string(kMaxTreeDepth));
  for (std::size_t c = 0; c < f.forests.size(); ++c) {
    const std::size_t features = f.deltas[c].size();
    if (f.anchor_idx[c].size() != features || features == 0 || features > 65535)
      fail("cascade " + std::to_string(c) + ": bad feature pixel table");
    for (unsigned long a : f.anchor_idx[c])
      if (a >= static_cast<unsigned long>(kNumLandmarks)) fail("feature pixel anchored to a missing landmark");
    for (const auto& tree : f.forests[c]) {
      if (tree.splits.size() != splits || tree.leaf_values.size() != splits + 1)
        fail("trees of different depths (cascade " + std::to_string(c) + ")");
      for (const auto& s : tree.splits)
        if (s.idx1 >= features || s.idx2 >= features) fail("split refers to a missing feature pixel");
      for (const auto& leaf : tree.leaf_values)
        if (leaf.size() != 2 * kNumLandmarks) fail("leaf of the wrong size");
    }
  }
}

// Umeyama's least-squares similarity transform (the formulas dlib's
// find_similarity_transform uses) from `from` to `to`, both x,y interleaved: the linear
// part only, in closed form for 2D instead of dlib's SVD. For a rotation,
// cR = [[p, -q], [q, p]] / sum|f|^2 with p = sum f.t and q = sum f x t over centred points;
// when det(cov) < 0 Umeyama's reflection gives [[r, s], [s, -r]] / sum|f|^2.
Eigen::Matrix2f similarity_linear_part(const float* from, const float* to) {
  double mean_from[2] = {0, 0}, mean_to[2] = {0, 0};
  for (int i = 0; i < kNumLandmarks; ++i)
    for (int k = 0; k < 2; ++k) {
      mean_from[k] += from[2 * i + k];
      mean_to[k] += to[2 * i + k];
    }
  for (int k = 0; k < 2; ++k) {
    mean_from[k] /= kNumLandmarks;
    mean_to[k] /= kNumLandmarks;
  }
  double sigma_from = 0;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();  // sum (to - mean) (from - mean)^T
  for (int i = 0; i < kNumLandmarks; ++i) {
    const Eigen::Vector2d f(from[2 * i] - mean_from[0], from[2 * i + 1] - mean_from[1]);
    const Eigen::Vector2d t(to[2 * i] - mean_to[0], to[2 * i + 1] - mean_to[1]);
    sigma_from += f.squaredNorm();
    cov += t * f.transpose();
  }
  Eigen::Matrix2d m;
  if (cov.determinant() >= 0) {
    const double p = cov(0, 0) + cov(1, 1), q = cov(1, 0) - cov(0, 1);
    m << p, -q, q, p;
  } else {
    const double r = cov(0, 0) - cov(1, 1), s = cov(0, 1) + cov(1, 0);
    m << r, s, s, -r;
  }
  return (m / sigma_from).cast<float>();
}

}  // namespace

ShapePredictorData ShapePredictorData::read_dlib(std::istream& in) {
  const DlibFields f = read_fields(in);
  check_fields(f);

  ShapePredictorData d;
  const std::size_t splits = f.forests.front().front().splits.size();
  d.tree_depth_ = static_cast<int>(std::log2(static_cast<double>(splits + 1)));
  d.initial_shape_.assign(f.initial_shape.begin(), f.initial_shape.end());
  d.cascade_first_tree_.push_back(0);
  d.cascade_first_feature_.push_back(0);
  for (std::size_t c = 0; c < f.forests.size(); ++c) {
    for (std::size_t i = 0; i < f.deltas[c].size(); ++i) {
      d.anchor_.push_back(static_cast<std::uint16_t>(f.anchor_idx[c][i]));
      d.delta_.push_back(f.deltas[c][i].x());
      d.delta_.push_back(f.deltas[c][i].y());
    }
    for (const auto& tree : f.forests[c]) {
      for (const auto& s : tree.splits)
        d.splits_.push_back({static_cast<std::uint16_t>(s.idx1), static_cast<std::uint16_t>(s.idx2), s.thresh});
      for (const auto& leaf : tree.leaf_values) d.leaf_values_.insert(d.leaf_values_.end(), leaf.begin(), leaf.end());
    }
    d.cascade_first_tree_.push_back(d.cascade_first_tree_.back() + static_cast<int>(f.forests[c].size()));
    d.cascade_first_feature_.push_back(d.cascade_first_feature_.back() + static_cast<int>(f.deltas[c].size()));
    d.max_features_ = std::max(d.max_features_, static_cast<int>(f.deltas[c].size()));
  }
  return d;
}

FaceBox ShapePredictorData::box_for(const Landmarks2D& landmarks) const {
  constexpr int kFirst = ibug::kRightBrowFirst, kLast = 47;  // brows, nose, eyes: not moved by speech
  constexpr int kCount = kLast - kFirst + 1;
  Eigen::Vector2d mean_shape = Eigen::Vector2d::Zero(), mean_image = Eigen::Vector2d::Zero();
  for (int i = kFirst; i <= kLast; ++i) {
    mean_shape += Eigen::Vector2d(initial_shape_[2 * i], initial_shape_[2 * i + 1]);
    mean_image += landmarks.col(i);
  }
  mean_shape /= kCount;
  mean_image /= kCount;
  double cross = 0, norm = 0;
  for (int i = kFirst; i <= kLast; ++i) {
    const Eigen::Vector2d s = Eigen::Vector2d(initial_shape_[2 * i], initial_shape_[2 * i + 1]) - mean_shape;
    cross += s.dot(landmarks.col(i) - mean_image);
    norm += s.squaredNorm();
  }
  const double size = cross / norm;  // right - left of the box (= bottom - top: dlib boxes are square)
  const Eigen::Vector2d top_left = mean_image - size * mean_shape;
  FaceBox box;
  box.left = std::lround(top_left.x());
  box.top = std::lround(top_left.y());
  box.right = box.left + std::lround(size);
  box.bottom = box.top + std::lround(size);
  return box;
}

ShapePredictor::ShapePredictor(std::shared_ptr<const ShapePredictorData> data)
    : data_(std::move(data)),
      shape_(ShapePredictorData::kShapeSize),
      feature_pixels_(static_cast<std::size_t>(data_->max_features_per_cascade())),
      leaves_(static_cast<std::size_t>(data_->num_trees())) {}

// dlib's impl::extract_feature_pixel_values: each feature pixel is its anchor landmark plus
// its mean-shape offset turned by the similarity between the mean and the current shape,
// mapped from box units to the image and rounded to the nearest pixel; outside the image
// it reads 0.
void ShapePredictor::read_feature_pixels(const cv::Mat& gray, const FaceBox& box, int cascade) {
  const ShapePredictorData& d = *data_;
  const Eigen::Matrix2f tform = similarity_linear_part(d.initial_shape_.data(), shape_.data());
  const double box_w = static_cast<double>(box.right - box.left);
  const double box_h = static_cast<double>(box.bottom - box.top);
  const int first = d.cascade_first_feature_[cascade];
  const int count = d.cascade_first_feature_[cascade + 1] - first;
  for (int i = 0; i < count; ++i) {
    const int f = first + i;
    const float dx = d.delta_[2 * f], dy = d.delta_[2 * f + 1];
    const int a = d.anchor_[f];
    const float u = tform(0, 0) * dx + tform(0, 1) * dy + shape_[2 * a];
    const float v = tform(1, 0) * dx + tform(1, 1) * dy + shape_[2 * a + 1];
    const long x = static_cast<long>(std::floor(box_w * u + static_cast<double>(box.left) + 0.5));
    const long y = static_cast<long>(std::floor(box_h * v + static_cast<double>(box.top) + 0.5));
    const bool inside = x >= 0 && y >= 0 && x < gray.cols && y < gray.rows;
    feature_pixels_[i] = inside ? static_cast<float>(gray.ptr<std::uint8_t>(static_cast<int>(y))[x]) : 0.0f;
  }
}

float ShapePredictor::feature_contrast() const {
  const int count = data_->cascade_first_feature_.back() - data_->cascade_first_feature_[data_->num_cascades() - 1];
  const Eigen::Map<const Eigen::ArrayXf> pixels(feature_pixels_.data(), count);
  return std::sqrt((pixels - pixels.mean()).square().mean());
}

void ShapePredictor::predict(const cv::Mat& gray, const FaceBox& box, Landmarks2D& out) {
  const ShapePredictorData& d = *data_;
  constexpr int kShapeSize = ShapePredictorData::kShapeSize;
  const int splits = (1 << d.tree_depth_) - 1;
  std::copy(d.initial_shape_.begin(), d.initial_shape_.end(), shape_.begin());
  for (int c = 0; c < d.num_cascades(); ++c) {
    read_feature_pixels(gray, box, c);
    const int first_tree = d.cascade_first_tree_[c], end_tree = d.cascade_first_tree_[c + 1];
    // The pixels are fixed within a cascade, so all its trees are walked first; the leaf
    // vectors (scattered over ~65 MB) are then summed in dlib's order, fetched ahead.
    for (int t = first_tree; t < end_tree; ++t) {
      const ShapePredictorData::Split* tree = &d.splits_[static_cast<std::size_t>(t) * splits];
      int node = 0;
      while (node < splits) {
        const auto& s = tree[node];
        node = feature_pixels_[s.first] - feature_pixels_[s.second] > s.threshold ? 2 * node + 1 : 2 * node + 2;
      }
      leaves_[t] = static_cast<std::uint8_t>(node - splits);
    }
    const auto leaf_values = [&](int t) {
      return &d.leaf_values_[(static_cast<std::size_t>(t) * (splits + 1) + leaves_[t]) * kShapeSize];
    };
    constexpr int kPrefetchDistance = 4;
    for (int t = first_tree; t < end_tree; ++t) {
      if (t + kPrefetchDistance < end_tree) {
        const char* ahead = reinterpret_cast<const char*>(leaf_values(t + kPrefetchDistance));
        for (int byte = 0; byte < kShapeSize * 4; byte += 64) __builtin_prefetch(ahead + byte);
      }
      const float* increment = leaf_values(t);
      for (int k = 0; k < kShapeSize; ++k) shape_[k] += increment[k];
    }
  }
  const double box_w = static_cast<double>(box.right - box.left);
  const double box_h = static_cast<double>(box.bottom - box.top);
  for (int i = 0; i < kNumLandmarks; ++i) {
    out(0, i) = box_w * shape_[2 * i] + static_cast<double>(box.left);
    out(1, i) = box_h * shape_[2 * i + 1] + static_cast<double>(box.top);
  }
}

}  // namespace lipdrive
