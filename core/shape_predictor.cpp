#include "core/shape_predictor.hpp"

#include "core/checksum.hpp"
#include "core/statistics.hpp"

#include <dlib/image_processing/shape_predictor.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <bit>
#include <concepts>
#include <cstdint>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>

namespace lipdrive {
namespace {

constexpr int kMaxTreeDepth = 8;  // leaf indices are stored in 8 bits
// The largest leaf increment either file may hold, in box units (dlib's 68-point model's is
// 0.07): with it the shape stays within the range where its pixel positions are integers.
constexpr float kMaxLeafIncrement = 16.0f;
constexpr float kLeafSteps = (1 << 23) - 1;  // a leaf's largest |increment| as a 24-bit integer
// The largest |coordinate| of the mean shape and of a feature pixel's offset from its anchor,
// in box units (dlib's 68-point model's lie within 0.03..1.07 and -0.19..0.19): with the leaves' bound
// the shape and its pixel positions stay finite and far inside the range of a long.
constexpr float kMaxShapeCoordinate = 16.0f;

bool within_shape_range(std::span<const float> values) {
  return std::all_of(values.begin(), values.end(), [](float v) { return std::abs(v) <= kMaxShapeCoordinate; });
}
constexpr const char* kShapeRangeError = "a mean shape or feature pixel offset that is not within 16 box sizes";

struct DlibFields {
  dlib::matrix<float, 0, 1> initial_shape;
  std::vector<std::vector<dlib::impl::regression_tree>> forests;
  std::vector<std::vector<unsigned long>> anchor_idx;
  std::vector<std::vector<dlib::vector<float, 2>>> deltas;
};

/// dlib's serialisation of a shape predictor, read with every count checked before it is
/// used: an element takes at least one byte, so a count beyond the bytes left in the stream
/// is a corrupt file, and vectors grow only with the elements actually read. dlib's
/// deserialize(std::vector&) and deserialize(matrix&) would first allocate whatever a corrupt
/// count says (gigabytes), then fail. Numbers are decoded here too, in dlib's encoding but
/// with unsigned arithmetic and range checks: dlib's own integer decoder overflows a signed
/// integer (undefined behaviour) on a magnitude the type cannot hold.
class DlibReader {
 public:
  /// `in` must be seekable (a file or a string): its size bounds every count.
  explicit DlibReader(std::istream& in) : in_(in) {
    const std::istream::pos_type start = in.tellg();
    in.seekg(0, std::ios::end);
    end_ = in.tellg();
    in.seekg(start);
    if (start == std::istream::pos_type(-1) || end_ == std::istream::pos_type(-1) || !in)
      throw ShapePredictorFormatError("cannot tell the size of the input");
  }

  /// An integer in dlib's encoding (dlib/serialize.h, pack_int): a control byte whose low four
  /// bits give the number of bytes that follow (1 to sizeof(T)) and whose top bit marks a
  /// negative value, then the magnitude, least significant byte first.
  template <std::integral T>
  void number(T& value) {
    const int control = in_.rdbuf()->sbumpc();
    if (control == std::char_traits<char>::eof()) fail("the file ends inside a number");
    const auto size = static_cast<std::streamsize>(control & 0x0F);
    const bool negative = (control & 0x80) != 0;
    if (size == 0 || size > static_cast<std::streamsize>(sizeof(T)))
      fail("a number of " + std::to_string(size) + " bytes where " + std::to_string(sizeof(T)) + " at most fit");
    std::array<unsigned char, 8> bytes{};
    if (in_.rdbuf()->sgetn(reinterpret_cast<char*>(bytes.data()), size) != size)
      fail("the file ends inside a number");
    std::uint64_t magnitude = 0;
    for (auto i = static_cast<std::size_t>(size); i-- > 0;) magnitude = magnitude << 8 | bytes[i];
    constexpr auto max = static_cast<std::uint64_t>(std::numeric_limits<T>::max());
    if (!negative && magnitude <= max) {
      value = static_cast<T>(magnitude);
      return;
    }
    if constexpr (std::is_signed_v<T>) {
      if (negative && magnitude <= max + 1) {  // -magnitude, without forming +magnitude in T
        value = magnitude == 0 ? T{0} : static_cast<T>(-static_cast<T>(magnitude - 1) - 1);
        return;
      }
    }
    fail(std::string(negative ? "-" : "") + std::to_string(magnitude) + " does not fit the number read");
  }

  /// A float in dlib's encoding (dlib/serialize.h, deserialize_floating_point): a mantissa
  /// (int64) and an exponent (int16) as two integers above, converted by dlib's float_details
  /// (mantissa * 2^exponent, three exponents reserved for infinities and NaN). A first byte
  /// with any of the bits 0x70 set is dlib's older text encoding, which dlib's reader reads.
  void number(float& value) {
    const int first = in_.rdbuf()->sgetc();
    if (first != std::char_traits<char>::eof() && (first & 0x70) != 0) {
      if (dlib::old_deserialize_floating_point(value, in_)) fail("a malformed number in dlib's text encoding");
      return;
    }
    std::int64_t mantissa = 0;
    std::int16_t exponent = 0;
    number(mantissa);
    number(exponent);
    value = static_cast<float>(dlib::float_details(mantissa, exponent));
  }

  /// std::vector<T>: its count, then each element read by `element(T&)`.
  template <class T, class ReadElement>
  void vector(std::vector<T>& out, const char* what, ReadElement element) {
    unsigned long count = 0;
    number(count);
    check_count(count, what);
    out.clear();
    for (unsigned long i = 0; i < count; ++i) element(out.emplace_back());
  }

  /// dlib::matrix<float, 0, 1>: rows and columns (both negated by newer dlib), then the values.
  void column(dlib::matrix<float, 0, 1>& out, const char* what) {
    long rows = 0, columns = 0;
    number(rows);
    number(columns);
    if (columns == -1) rows = rows == std::numeric_limits<long>::min() ? -1 : -rows;
    if ((columns != 1 && columns != -1) || rows < 0)
      throw ShapePredictorFormatError(std::string(what) + " is not a column of values");
    check_count(static_cast<unsigned long>(rows), what);
    out.set_size(rows);
    for (long i = 0; i < rows; ++i) number(out(i));
  }

 private:
  [[noreturn]] void fail(const std::string& what) {
    throw ShapePredictorFormatError("not a dlib shape predictor: " + what + " (at byte " +
                                    std::to_string(static_cast<long long>(in_.tellg())) + ")");
  }

  void check_count(unsigned long count, const char* what) {
    const std::istream::pos_type at = in_.tellg();
    const auto left = static_cast<unsigned long>(end_ - at);
    if (count > left)
      throw ShapePredictorFormatError(std::string(what) + ": a count of " + std::to_string(count) + " at byte " +
                                      std::to_string(static_cast<long long>(at)) + " with only " +
                                      std::to_string(left) + " bytes left");
  }

  std::istream& in_;
  std::istream::pos_type end_;
};

// The order of dlib's deserialize(shape_predictor&, istream&) (shape_predictor.h) and of the
// deserialize functions it calls for its members.
DlibFields read_fields(std::istream& in) {
  DlibFields f;
  DlibReader read(in);
  int version = 0;
  read.number(version);
  if (version != 1)
    throw ShapePredictorFormatError("not a dlib shape predictor (version " + std::to_string(version) + ")");
  read.column(f.initial_shape, "initial shape");
  read.vector(f.forests, "cascades", [&](std::vector<dlib::impl::regression_tree>& forest) {
    read.vector(forest, "trees", [&](dlib::impl::regression_tree& tree) {
      read.vector(tree.splits, "splits", [&](dlib::impl::split_feature& split) {
        read.number(split.idx1);
        read.number(split.idx2);
        read.number(split.thresh);
      });
      read.vector(tree.leaf_values, "leaves", [&](dlib::matrix<float, 0, 1>& leaf) { read.column(leaf, "leaf"); });
    });
  });
  read.vector(f.anchor_idx, "cascades", [&](std::vector<unsigned long>& anchors) {
    read.vector(anchors, "anchors", [&](unsigned long& anchor) { read.number(anchor); });
  });
  read.vector(f.deltas, "cascades", [&](std::vector<dlib::vector<float, 2>>& deltas) {
    read.vector(deltas, "feature pixels", [&](dlib::vector<float, 2>& delta) {
      read.number(delta.x());
      read.number(delta.y());
    });
  });
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
  if (!within_shape_range(std::span(&f.initial_shape(0), f.initial_shape.size()))) fail(kShapeRangeError);
  for (std::size_t c = 0; c < f.forests.size(); ++c) {
    const std::size_t features = f.deltas[c].size();
    for (const auto& delta : f.deltas[c])
      if (!within_shape_range(std::array{delta.x(), delta.y()})) fail(kShapeRangeError);
    if (f.anchor_idx[c].size() != features || features == 0 || features > 65535)
      fail("cascade " + std::to_string(c) + ": bad feature pixel table");
    for (unsigned long a : f.anchor_idx[c])
      if (a >= static_cast<unsigned long>(kNumLandmarks)) fail("feature pixel anchored to a missing landmark");
    // As read_compact() checks them, so that every .dat read converts to an .lpp that reads.
    if (f.forests[c].empty()) fail("cascade " + std::to_string(c) + " has no trees");
    for (const auto& tree : f.forests[c]) {
      if (tree.splits.size() != splits || tree.leaf_values.size() != splits + 1)
        fail("trees of different depths (cascade " + std::to_string(c) + ")");
      for (const auto& s : tree.splits) {
        if (s.idx1 >= features || s.idx2 >= features) fail("split refers to a missing feature pixel");
        if (!std::isfinite(s.thresh)) fail("a split threshold that is not a finite number");
      }
      for (const auto& leaf : tree.leaf_values) {
        if (leaf.size() != 2 * kNumLandmarks) fail("leaf of the wrong size");
        for (const float v : leaf)
          if (!(std::abs(v) <= kMaxLeafIncrement)) fail("a leaf increment that is not a finite number of box sizes");
      }
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

/// The arrays read_dlib builds and the spans of ShapePredictorData point into.
struct OwnedArrays {
  std::vector<float> initial_shape;
  std::vector<std::int32_t> cascade_first_tree, cascade_first_feature;
  std::vector<std::uint16_t> anchor;
  std::vector<float> delta;
  std::vector<ShapePredictorData::Split> splits;
  std::vector<ShapePredictorData::Leaf> leaf_increments;
};

/// A dlib leaf's increments as 24-bit integers with their own scale (ShapePredictorData::Leaf).
ShapePredictorData::Leaf quantised(const dlib::matrix<float, 0, 1>& increments) {
  ShapePredictorData::Leaf leaf{};
  float largest = 0;
  for (const float v : increments) largest = std::max(largest, std::abs(v));
  leaf.scale = largest / kLeafSteps;
  if (largest == 0) return leaf;  // all zero
  for (int k = 0; k < ShapePredictorData::kShapeSize; ++k) {
    const auto q = static_cast<std::int32_t>(
        std::clamp(std::lround(increments(k) / leaf.scale), -static_cast<long>(kLeafSteps), static_cast<long>(kLeafSteps)));
    leaf.high[k] = static_cast<std::int16_t>(q >> 8);  // floor(q / 256): q = 256 high + low
    leaf.low[k] = static_cast<std::uint8_t>(q & 0xFF);
  }
  return leaf;
}

int largest_cascade(std::span<const std::int32_t> first_feature) {
  int largest = 0;
  for (std::size_t c = 1; c < first_feature.size(); ++c)
    largest = std::max(largest, first_feature[c] - first_feature[c - 1]);
  return largest;
}

// --- the .lpp file (layout in shape_predictor.hpp) ---------------------------------------

static_assert(std::endian::native == std::endian::little, "the .lpp file is mapped as little-endian arrays");
static_assert(sizeof(ShapePredictorData::Split) == 8 && std::is_trivially_copyable_v<ShapePredictorData::Split>);
static_assert(sizeof(ShapePredictorData::Leaf) == 412 && alignof(ShapePredictorData::Leaf) == 4 &&
              std::is_trivially_copyable_v<ShapePredictorData::Leaf>);

constexpr std::string_view kCompactMagic{"LPDPRED\0", 8};
constexpr std::uint32_t kCompactVersion = 2;
constexpr std::size_t kCompactHeaderSize = 64, kCompactAlignment = 64;
// Bounds on a header's counts (dlib's 68-point model: 15 cascades, 7,500 trees, 7,500 feature
// pixels), so that a forged header cannot make the sizes below overflow.
constexpr std::uint32_t kMaxCompactTrees = 1u << 20, kMaxCompactFeatures = 1u << 24;

struct CompactCounts {
  std::uint32_t depth, cascades, trees, features;
  std::uint64_t detector_bytes;
};

/// Where each array of the payload starts, and where the file ends.
struct CompactLayout {
  std::size_t initial_shape, cascade_first_tree, cascade_first_feature, anchor, delta, splits, leaf_increments, detector,
      end;
};

CompactLayout compact_layout(const CompactCounts& n) {
  const std::size_t splits_per_tree = (std::size_t{1} << n.depth) - 1;
  std::size_t at = kCompactHeaderSize;
  const auto next = [&](std::size_t bytes) {
    const std::size_t start = at;
    at = (at + bytes + kCompactAlignment - 1) / kCompactAlignment * kCompactAlignment;
    return start;
  };
  CompactLayout l{};
  l.initial_shape = next(ShapePredictorData::kShapeSize * sizeof(float));
  l.cascade_first_tree = next((n.cascades + 1) * sizeof(std::int32_t));
  l.cascade_first_feature = next((n.cascades + 1) * sizeof(std::int32_t));
  l.anchor = next(n.features * sizeof(std::uint16_t));
  l.delta = next(2 * std::size_t{n.features} * sizeof(float));
  l.splits = next(n.trees * splits_per_tree * sizeof(ShapePredictorData::Split));
  l.leaf_increments = next(n.trees * (splits_per_tree + 1) * sizeof(ShapePredictorData::Leaf));
  l.detector = at;
  l.end = at + n.detector_bytes;
  return l;
}

void put_u32(std::vector<std::uint8_t>& file, std::size_t offset, std::uint32_t v) {
  std::memcpy(file.data() + offset, &v, sizeof v);
}
void put_u64(std::vector<std::uint8_t>& file, std::size_t offset, std::uint64_t v) {
  std::memcpy(file.data() + offset, &v, sizeof v);
}
std::uint32_t get_u32(std::span<const std::uint8_t> bytes, std::size_t offset) {
  std::uint32_t v;
  std::memcpy(&v, bytes.data() + offset, sizeof v);
  return v;
}
std::uint64_t get_u64(std::span<const std::uint8_t> bytes, std::size_t offset) {
  std::uint64_t v;
  std::memcpy(&v, bytes.data() + offset, sizeof v);
  return v;
}

/// `count` values of type T at `offset` of a mapped file, in place: the layout aligns every
/// array to 64 bytes and the mapping starts on a page, so they are aligned for T.
template <typename T>
std::span<const T> view_of(std::span<const std::uint8_t> bytes, std::size_t offset, std::size_t count) {
  static_assert(std::is_trivially_copyable_v<T>);
  return {reinterpret_cast<const T*>(bytes.data() + offset), count};
}

/// dlib's unnormalizing_tform: box units (the box's top left corner 0, its bottom right 1) to
/// image pixels, and then, for a turned box, the turn about the box's centre. An upright box
/// computes exactly what dlib does (the turn is skipped, not multiplied by 1).
class BoxToImage {
 public:
  explicit BoxToImage(const FaceBox& box)
      : width_(static_cast<double>(box.right - box.left)),
        height_(static_cast<double>(box.bottom - box.top)),
        left_(static_cast<double>(box.left)),
        top_(static_cast<double>(box.top)),
        centre_(0.5 * static_cast<double>(box.left + box.right), 0.5 * static_cast<double>(box.top + box.bottom)),
        turned_(box.roll != 0),
        turn_(Eigen::Rotation2Dd(box.roll).toRotationMatrix()) {}

  Eigen::Vector2d operator()(double u, double v) const {
    const Eigen::Vector2d upright(width_ * u + left_, height_ * v + top_);
    return turned_ ? Eigen::Vector2d(centre_ + turn_ * (upright - centre_)) : upright;
  }

 private:
  double width_, height_, left_, top_;
  Eigen::Vector2d centre_;
  bool turned_;
  Eigen::Matrix2d turn_;
};

}  // namespace

ShapePredictorData ShapePredictorData::read_dlib(std::istream& in, FaceDetector (*detector)()) {
  const DlibFields f = read_fields(in);
  check_fields(f);

  auto a = std::make_shared<OwnedArrays>();
  const std::size_t splits = f.forests.front().front().splits.size();
  a->initial_shape.assign(f.initial_shape.begin(), f.initial_shape.end());
  a->cascade_first_tree.push_back(0);
  a->cascade_first_feature.push_back(0);
  for (std::size_t c = 0; c < f.forests.size(); ++c) {
    for (std::size_t i = 0; i < f.deltas[c].size(); ++i) {
      a->anchor.push_back(static_cast<std::uint16_t>(f.anchor_idx[c][i]));
      a->delta.push_back(f.deltas[c][i].x());
      a->delta.push_back(f.deltas[c][i].y());
    }
    for (const auto& tree : f.forests[c]) {
      for (const auto& s : tree.splits)
        a->splits.push_back({static_cast<std::uint16_t>(s.idx1), static_cast<std::uint16_t>(s.idx2), s.thresh});
      for (const auto& leaf : tree.leaf_values) a->leaf_increments.push_back(quantised(leaf));
    }
    a->cascade_first_tree.push_back(a->cascade_first_tree.back() + static_cast<std::int32_t>(f.forests[c].size()));
    a->cascade_first_feature.push_back(a->cascade_first_feature.back() + static_cast<std::int32_t>(f.deltas[c].size()));
  }

  ShapePredictorData d(detector());
  d.tree_depth_ = static_cast<int>(std::log2(static_cast<double>(splits + 1)));
  d.initial_shape_ = a->initial_shape;
  d.cascade_first_tree_ = a->cascade_first_tree;
  d.cascade_first_feature_ = a->cascade_first_feature;
  d.anchor_ = a->anchor;
  d.delta_ = a->delta;
  d.splits_ = a->splits;
  d.leaf_increments_ = a->leaf_increments;
  d.max_features_ = largest_cascade(d.cascade_first_feature_);
  d.storage_ = std::move(a);
  return d;
}

std::vector<std::uint8_t> ShapePredictorData::write_compact() const {
  const std::vector<std::uint8_t> detector = detector_.serialize();
  const CompactCounts counts{static_cast<std::uint32_t>(tree_depth_), static_cast<std::uint32_t>(num_cascades()),
                             static_cast<std::uint32_t>(num_trees()),
                             static_cast<std::uint32_t>(cascade_first_feature_.back()), detector.size()};
  const CompactLayout layout = compact_layout(counts);
  std::vector<std::uint8_t> file(layout.end, 0);
  const auto put = [&](std::size_t offset, const auto& values) {
    std::memcpy(file.data() + offset, values.data(), values.size_bytes());
  };
  put(layout.initial_shape, initial_shape_);
  put(layout.cascade_first_tree, cascade_first_tree_);
  put(layout.cascade_first_feature, cascade_first_feature_);
  put(layout.anchor, anchor_);
  put(layout.delta, delta_);
  put(layout.splits, splits_);
  put(layout.leaf_increments, leaf_increments_);
  put(layout.detector, std::span(detector));

  std::memcpy(file.data(), kCompactMagic.data(), kCompactMagic.size());
  put_u32(file, 8, kCompactVersion);
  put_u32(file, 12, kNumLandmarks);
  put_u32(file, 16, counts.depth);
  put_u32(file, 20, counts.cascades);
  put_u32(file, 24, counts.trees);
  put_u32(file, 28, counts.features);
  put_u64(file, 32, counts.detector_bytes);
  put_u64(file, 40, layout.end - kCompactHeaderSize);
  put_u32(file, 48, crc32(std::span(file).subspan(kCompactHeaderSize)));
  return file;
}

bool ShapePredictorData::is_compact(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= kCompactMagic.size() &&
         std::memcmp(bytes.data(), kCompactMagic.data(), kCompactMagic.size()) == 0;
}

ShapePredictorData ShapePredictorData::read_compact(std::span<const std::uint8_t> bytes,
                                                    std::shared_ptr<const void> owner) {
  const auto fail = [](const std::string& what) -> void { throw ShapePredictorFormatError(what); };
  if (!is_compact(bytes) || bytes.size() < kCompactHeaderSize)
    fail("not a lipdrive predictor file (no LPDPRED header)");
  if (const std::uint32_t version = get_u32(bytes, 8); version != kCompactVersion)
    fail("predictor file version " + std::to_string(version) + "; this lipdrive reads version " +
         std::to_string(kCompactVersion) + " (convert the predictor again: lipdrive predictor convert)");
  if (const std::uint32_t landmarks = get_u32(bytes, 12); landmarks != kNumLandmarks)
    fail("predicts " + std::to_string(landmarks) + " landmarks; lipdrive needs the 68 iBUG landmarks");
  const CompactCounts counts{get_u32(bytes, 16), get_u32(bytes, 20), get_u32(bytes, 24), get_u32(bytes, 28),
                             get_u64(bytes, 32)};
  if (counts.depth < 1 || counts.depth > kMaxTreeDepth || counts.cascades < 1 || counts.trees < counts.cascades ||
      counts.features < counts.cascades || counts.trees > kMaxCompactTrees || counts.features > kMaxCompactFeatures ||
      counts.detector_bytes > bytes.size())
    fail("implausible sizes in the header");
  const CompactLayout layout = compact_layout(counts);
  if (get_u64(bytes, 40) != layout.end - kCompactHeaderSize || bytes.size() != layout.end)
    fail("the file is " + std::to_string(bytes.size()) + " bytes; its header says " + std::to_string(layout.end) +
         " (truncated or padded)");
  if (crc32(bytes.subspan(kCompactHeaderSize)) != get_u32(bytes, 48)) fail("checksum mismatch (the file is corrupt)");

  ShapePredictorData d([&] {
    try {
      return FaceDetector::deserialize(bytes.subspan(layout.detector, counts.detector_bytes));
    } catch (const std::runtime_error& e) {
      throw ShapePredictorFormatError(e.what());
    }
  }());
  const std::size_t splits_per_tree = (std::size_t{1} << counts.depth) - 1, leaves_per_tree = splits_per_tree + 1;
  d.tree_depth_ = static_cast<int>(counts.depth);
  d.initial_shape_ = view_of<float>(bytes, layout.initial_shape, kShapeSize);
  d.cascade_first_tree_ = view_of<std::int32_t>(bytes, layout.cascade_first_tree, counts.cascades + 1);
  d.cascade_first_feature_ = view_of<std::int32_t>(bytes, layout.cascade_first_feature, counts.cascades + 1);
  d.anchor_ = view_of<std::uint16_t>(bytes, layout.anchor, counts.features);
  d.delta_ = view_of<float>(bytes, layout.delta, 2 * std::size_t{counts.features});
  d.splits_ = view_of<Split>(bytes, layout.splits, counts.trees * splits_per_tree);
  d.leaf_increments_ = view_of<Leaf>(bytes, layout.leaf_increments, counts.trees * leaves_per_tree);

  // Every offset and index, before anything is evaluated.
  const auto ascending = [&](std::span<const std::int32_t> first, std::uint32_t total, int max_step) {
    if (first.front() != 0 || first.back() != static_cast<std::int32_t>(total)) return false;
    for (std::size_t c = 1; c < first.size(); ++c)
      if (first[c] <= first[c - 1] || first[c] - first[c - 1] > max_step) return false;
    return true;
  };
  if (!ascending(d.cascade_first_tree_, counts.trees, static_cast<int>(kMaxCompactTrees)) ||
      !ascending(d.cascade_first_feature_, counts.features, 65535))
    fail("bad cascade table");
  for (const std::uint16_t a : d.anchor_)
    if (a >= kNumLandmarks) fail("feature pixel anchored to a missing landmark");
  for (int c = 0; c < static_cast<int>(counts.cascades); ++c) {
    const int features = d.cascade_first_feature_[c + 1] - d.cascade_first_feature_[c];
    const auto first = static_cast<std::size_t>(d.cascade_first_tree_[c]) * splits_per_tree;
    const auto end = static_cast<std::size_t>(d.cascade_first_tree_[c + 1]) * splits_per_tree;
    for (std::size_t i = first; i < end; ++i) {
      if (d.splits_[i].first >= features || d.splits_[i].second >= features)
        fail("split " + std::to_string(i) + " refers to a missing feature pixel");
      if (!std::isfinite(d.splits_[i].threshold))
        fail("split " + std::to_string(i) + ": a threshold that is not a finite number");
    }
  }
  if (!within_shape_range(d.initial_shape_) || !within_shape_range(d.delta_)) fail(kShapeRangeError);
  for (const Leaf& leaf : d.leaf_increments_)
    if (!(leaf.scale >= 0 && leaf.scale <= kMaxLeafIncrement / kLeafSteps)) fail("a leaf scale out of range");
  d.max_features_ = largest_cascade(d.cascade_first_feature_);
  d.storage_ = std::move(owner);
  return d;
}

FaceBox ShapePredictorData::box_for(const Landmarks2D& landmarks, double upright) const {
  // The face's roll is the turn of the similarity from the mean shape to the landmarks, least
  // squares (Umeyama, "Least-squares estimation of transformation parameters between two
  // point patterns", PAMI 1991, in two dimensions): atan2(sum s x t, sum s.t) over the centred
  // points. With the box's turn fixed, the least-squares scale is the centred landmarks'
  // projection on the turned mean shape, and the mean shape's centroid meets theirs.
  constexpr int kFirst = ibug::kRightBrowFirst, kLast = 47;  // brows, nose, eyes: not moved by speech
  constexpr int kCount = kLast - kFirst + 1;
  const auto mean_point = [&](int i) { return Eigen::Vector2d(initial_shape_[2 * i], initial_shape_[2 * i + 1]); };
  Eigen::Vector2d mean_shape = Eigen::Vector2d::Zero(), mean_image = Eigen::Vector2d::Zero();
  for (int i = kFirst; i <= kLast; ++i) {
    mean_shape += mean_point(i);
    mean_image += landmarks.col(i);
  }
  mean_shape /= kCount;
  mean_image /= kCount;
  double dot = 0, cross = 0, norm = 0;
  for (int i = kFirst; i <= kLast; ++i) {
    const Eigen::Vector2d s = mean_point(i) - mean_shape, t = landmarks.col(i) - mean_image;
    dot += s.dot(t);
    cross += s.x() * t.y() - s.y() * t.x();
    norm += s.squaredNorm();
  }
  const double face_roll = std::atan2(cross, dot);
  const double roll = std::copysign(std::max(0.0, std::abs(face_roll) - upright), face_roll);
  const Eigen::Matrix2d turn = Eigen::Rotation2Dd(roll).toRotationMatrix();
  // right - left of the box (= bottom - top: dlib boxes are square)
  const double size = (dot * turn(0, 0) + cross * turn(1, 0)) / norm;
  const Eigen::Vector2d centre = mean_image - turn * (size * (mean_shape - Eigen::Vector2d(0.5, 0.5)));
  const Eigen::Vector2d top_left = centre - Eigen::Vector2d(0.5 * size, 0.5 * size);
  FaceBox box;
  box.left = std::lround(top_left.x());
  box.top = std::lround(top_left.y());
  box.right = box.left + std::lround(size);
  box.bottom = box.top + std::lround(size);
  box.roll = roll;
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
// it reads 0 (or, kMirrored, the pixel mirrored at the edge).
void ShapePredictor::read_feature_pixels(const cv::Mat& gray, const FaceBox& box, int cascade, BeyondTheEdge beyond) {
  const ShapePredictorData& d = *data_;
  const Eigen::Matrix2f tform = similarity_linear_part(d.initial_shape_.data(), shape_.data());
  const BoxToImage to_image(box);
  const int first = d.cascade_first_feature_[cascade];
  const int count = d.cascade_first_feature_[cascade + 1] - first;
  for (int i = 0; i < count; ++i) {
    const int f = first + i;
    const float dx = d.delta_[2 * f], dy = d.delta_[2 * f + 1];
    const int a = d.anchor_[f];
    const float u = tform(0, 0) * dx + tform(0, 1) * dy + shape_[2 * a];
    const float v = tform(1, 0) * dx + tform(1, 1) * dy + shape_[2 * a + 1];
    const Eigen::Vector2d p = to_image(u, v);
    // Compared before the conversion to an integer, which only an in-range value may take.
    double x = std::floor(p.x() + 0.5);
    double y = std::floor(p.y() + 0.5);
    if (beyond == BeyondTheEdge::kMirrored) {
      x = x < 0 ? -x : x >= gray.cols ? 2.0 * (gray.cols - 1) - x : x;
      y = y < 0 ? -y : y >= gray.rows ? 2.0 * (gray.rows - 1) - y : y;
    }
    const bool inside = x >= 0 && y >= 0 && x < gray.cols && y < gray.rows;
    feature_pixels_[i] =
        inside ? static_cast<float>(gray.ptr<std::uint8_t>(static_cast<int>(y))[static_cast<int>(x)]) : 0.0f;
  }
}

float ShapePredictor::feature_contrast() const {
  const int count = data_->cascade_first_feature_.back() - data_->cascade_first_feature_[data_->num_cascades() - 1];
  const Eigen::Map<const Eigen::ArrayXf> pixels(feature_pixels_.data(), count);
  return std::sqrt((pixels - pixels.mean()).square().mean());
}

const ShapePredictorData::Leaf& ShapePredictor::chosen_leaf(int tree) const {
  const int leaves_per_tree = 1 << data_->tree_depth_;
  return data_->leaf_increments_[static_cast<std::size_t>(tree) * leaves_per_tree + leaves_[tree]];
}

void ShapePredictor::predict(const cv::Mat& gray, const FaceBox& box, Landmarks2D& out, BeyondTheEdge beyond) {
  const ShapePredictorData& d = *data_;
  constexpr int kShapeSize = ShapePredictorData::kShapeSize;
  const int splits = (1 << d.tree_depth_) - 1;
  std::copy(d.initial_shape_.begin(), d.initial_shape_.end(), shape_.begin());
  for (int c = 0; c < d.num_cascades(); ++c) {
    read_feature_pixels(gray, box, c, beyond);
    const int first_tree = d.cascade_first_tree_[c], end_tree = d.cascade_first_tree_[c + 1];
    // The pixels are fixed within a cascade, so all its trees are walked first; the leaf
    // vectors (scattered over ~49 MB) are then summed in dlib's order, fetched ahead.
    // kLanes trees descend level by level together: their walks do not depend on each other,
    // so the processor overlaps them, and each step is a comparison turned into the child's
    // index, not a branch it would mispredict half the time.
    constexpr int kLanes = 8;
    for (int t = first_tree; t < end_tree; t += kLanes) {
      const int lanes = std::min(kLanes, end_tree - t);
      std::array<int, kLanes> node{};
      for (int level = 0; level < d.tree_depth_; ++level)
        for (int lane = 0; lane < lanes; ++lane) {
          const auto& s = d.splits_[static_cast<std::size_t>(t + lane) * splits + node[lane]];
          const bool left = feature_pixels_[s.first] - feature_pixels_[s.second] > s.threshold;
          node[lane] = 2 * node[lane] + 2 - static_cast<int>(left);
        }
      for (int lane = 0; lane < lanes; ++lane) leaves_[t + lane] = static_cast<std::uint8_t>(node[lane] - splits);
    }
    constexpr int kPrefetchDistance = 24;
    for (int t = first_tree; t < end_tree; ++t) {
      if (t + kPrefetchDistance < end_tree) {
        const char* ahead = reinterpret_cast<const char*>(&chosen_leaf(t + kPrefetchDistance));
        for (std::size_t byte = 0; byte < sizeof(ShapePredictorData::Leaf); byte += 64) __builtin_prefetch(ahead + byte);
        __builtin_prefetch(ahead + sizeof(ShapePredictorData::Leaf) - 1);  // a leaf starts anywhere in a line
      }
      const ShapePredictorData::Leaf& increments = chosen_leaf(t);
      for (int k = 0; k < kShapeSize; ++k) shape_[k] += increments.increment(k);
    }
  }
  const BoxToImage to_image(box);
  for (int i = 0; i < kNumLandmarks; ++i) out.col(i) = to_image(shape_[2 * i], shape_[2 * i + 1]);
}

void ShapePredictor::warm() const {
  const ShapePredictorData& d = *data_;
  const int splits = (1 << d.tree_depth_) - 1;
  // A load of one byte per 64-byte line; volatile, so that the compiler keeps loads whose
  // values are not used. Not prefetch hints: a processor may drop those when its line-fill
  // buffers are full (on 12-04 hints alone brought back little of the paced cost).
  const auto read = [](const void* first, std::size_t bytes) {
    const auto* p = static_cast<const volatile unsigned char*>(first);
    for (std::size_t byte = 0; byte < bytes; byte += 64) (void)p[byte];
    (void)p[bytes - 1];  // an object starts anywhere in a line
  };
  read(d.anchor_.data(), d.anchor_.size_bytes());
  read(d.delta_.data(), d.delta_.size_bytes());
  for (int t = 0; t < d.num_trees(); ++t) {
    read(&d.splits_[static_cast<std::size_t>(t) * splits], splits * sizeof(ShapePredictorData::Split));
    read(&chosen_leaf(t), sizeof(ShapePredictorData::Leaf));
  }
}

void ShapePredictor::predict_median(const cv::Mat& gray, const FaceBox& box, Landmarks2D& out) {
  // {scale, shift across, shift down} of the boxes around `box`, in box sizes.
  static constexpr std::array<std::array<double, 3>, kStarts - 1> kAround{
      {{0.95, 0, 0}, {1.05, 0, 0}, {1, -0.03, 0}, {1, 0.03, 0}, {1, 0, -0.03}, {1, 0, 0.03}}};
  const double width = static_cast<double>(box.width()), height = static_cast<double>(box.height());
  const double centre_x = 0.5 * static_cast<double>(box.left + box.right);
  const double centre_y = 0.5 * static_cast<double>(box.top + box.bottom);
  const double cos_roll = std::cos(box.roll), sin_roll = std::sin(box.roll);
  for (std::size_t k = 0; k < kAround.size(); ++k) {
    const auto [scale, across, down] = kAround[k];  // along the box's own axes
    const double x = centre_x + cos_roll * across * width - sin_roll * down * height;
    const double y = centre_y + sin_roll * across * width + cos_roll * down * height;
    const double half_w = 0.5 * scale * width, half_h = 0.5 * scale * height;
    const FaceBox around{std::lround(x - half_w), std::lround(y - half_h), std::lround(x + half_w),
                         std::lround(y + half_h), box.roll};
    predict(gray, around, starts_[k]);
  }
  predict(gray, box, starts_[kStarts - 1]);  // last: feature_contrast() and last_leaves() are the box's
  std::array<double, kStarts> values;
  for (Eigen::Index i = 0; i < out.size(); ++i) {
    for (int k = 0; k < kStarts; ++k) values[k] = starts_[k](i);
    out(i) = median(values);
  }
}

}  // namespace lipdrive
