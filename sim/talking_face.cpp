#include "sim/talking_face.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lipdrive {
namespace {

using Vec2 = Eigen::Vector2d;

Vec2 point(const Landmarks2D& landmarks, int index) { return landmarks.col(index); }

double normaliser(const Landmarks2D& landmarks) { return mouth_ratios(landmarks).d; }

// Keyframes of the script: (time, open, spread, round). Transitions of 0.3-0.5 s are
// syllable rate; the silences are exactly closed and still.
struct Keyframe {
  double time_s;
  MouthPose pose;
};
constexpr Keyframe kScript[] = {
    {0.0, {0, 0, 0}},     {0.6, {0, 0, 0}},     {1.0, {0.6, 0, 0}},    {1.3, {0.2, 0, 0}},   {1.7, {1.0, 0, 0}},
    {2.1, {0, 0, 0}},     {2.6, {0, 0, 0}},     {3.0, {0.3, 1.0, 0}},  {3.4, {0.1, 0.6, 0}}, {3.8, {0.1, 0, 1.0}},
    {4.3, {0.4, 0, 0.6}}, {4.7, {0, 0, 0}},     {5.3, {0, 0, 0}},      {5.7, {0.8, 0.3, 0}}, {6.0, {0.35, 0, 0}},
    {6.4, {0.2, 0.8, 0}}, {6.8, {0.5, 0, 0.5}}, {7.1, {0.05, 0, 0.3}}, {7.5, {0.7, 0, 0}},   {7.9, {0, 0, 0}},
    {8.5, {0, 0, 0}},
};

double smoothstep(double t) { return t * t * (3 - 2 * t); }

MouthPose interpolate(const MouthPose& a, const MouthPose& b, double t) {
  const double s = smoothstep(t);
  return {a.open + s * (b.open - a.open), a.spread + s * (b.spread - a.spread), a.round + s * (b.round - a.round)};
}

// How much landmark i follows the chin when the jaw drops: the jaw rotates about the
// ears, so the chin moves most, the lower lip nearly as much, the corners a third.
double jaw_weight(int i) {
  switch (i) {
    case 3:
    case 13: return 0.12;
    case 4:
    case 12: return 0.35;
    case 5:
    case 11: return 0.6;
    case 6:
    case 10: return 0.8;
    case 7:
    case 9: return 0.95;
    case 8: return 1.0;
    case 48:
    case 54:
    case 60:
    case 64: return 0.35;  // corners
    case 55:
    case 59: return 0.55;
    case 56:
    case 58: return 0.8;
    case 57: return 0.85;
    case 65:
    case 67: return 0.75;
    case 66: return 0.9;
    default: return 0;
  }
}

bool is_lip(int i) { return i >= ibug::kMouthCornerRight; }
bool is_outer_upper_lip(int i) { return i >= 49 && i <= 53; }
bool is_outer_lower_lip(int i) { return i >= 55 && i <= 59; }
bool is_inner_upper_lip(int i) { return i >= 61 && i <= 63; }
bool is_inner_lower_lip(int i) { return i >= 65 && i <= 67; }

// Displacement (du, dv) of landmark i in units of d along the face axes (u towards the
// subject's left, v down the face); `across` is the point's u offset from the mouth
// centre in units of d. Spreading and rounding scale the lips sideways about the mouth
// centre, so inner and outer corners move together as on a real mouth. The magnitudes
// put a wide-open mouth at H/d ~ 0.5 and move each corner by up to ~0.14 d out (spread)
// or ~0.27 d in (round): the range of a speaking adult, short of folding the warp.
Vec2 displacement(int i, double across, const MouthPose& pose) {
  double du = 0;
  double dv = jaw_weight(i) * 0.5 * pose.open;
  if (!is_lip(i)) return {du, dv};

  du += across * (0.16 * pose.spread - 0.3 * pose.round - 0.04 * pose.open);
  // Opening lifts the upper lip a little.
  if (is_inner_upper_lip(i)) dv -= 0.06 * pose.open;
  if (is_outer_upper_lip(i)) dv -= 0.02 * pose.open;
  // Spreading lifts the corners and thins the lips.
  dv -= 0.035 * across * across * pose.spread;
  if (i >= 50 && i <= 52) dv += 0.02 * pose.spread;
  if (i >= 56 && i <= 58) dv -= 0.02 * pose.spread;
  // Rounding pushes the lips forward: taller, with a small round opening.
  if (is_outer_upper_lip(i)) dv -= 0.05 * pose.round;
  if (is_outer_lower_lip(i)) dv += 0.05 * pose.round;
  if (is_inner_upper_lip(i)) dv -= 0.04 * pose.round;
  if (is_inner_lower_lip(i)) dv += 0.04 * pose.round;
  return {du, dv};
}

cv::Point2d to_cv(const Vec2& p) { return {p.x(), p.y()}; }

double signed_area(const cv::Point2d& a, const cv::Point2d& b, const cv::Point2d& c) {
  return 0.5 * ((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y));
}

// Fixed control points: the frame border, and a ring around the jaw (the jaw contour
// pushed away from the nose tip), which confines the warp to the lower face and leaves
// room below the chin for the largest jaw drop.
std::vector<cv::Point2d> make_anchors(const Landmarks2D& landmarks, cv::Size frame) {
  std::vector<cv::Point2d> anchors;
  const double w = frame.width - 1, h = frame.height - 1;
  for (int k = 0; k <= 4; ++k) {
    anchors.push_back({w * k / 4, 0});
    anchors.push_back({w * k / 4, h});
  }
  for (int k = 1; k <= 3; ++k) {
    anchors.push_back({0, h * k / 4});
    anchors.push_back({w, h * k / 4});
  }
  const Vec2 nose = point(landmarks, ibug::kNoseTip);
  for (int i = ibug::kJawFirst; i <= ibug::kJawLast; i += 2) {
    const Vec2 ring = nose + 1.6 * (point(landmarks, i) - nose);
    anchors.push_back({std::clamp(ring.x(), 0.0, w), std::clamp(ring.y(), 0.0, h)});
  }
  return anchors;
}

// Delaunay triangles of the control points as index triples.
std::vector<std::array<int, 3>> triangulate(const std::vector<cv::Point2d>& points, cv::Size frame) {
  cv::Subdiv2D subdiv(cv::Rect(-1, -1, frame.width + 2, frame.height + 2));
  for (const auto& p : points) subdiv.insert(cv::Point2f(static_cast<float>(p.x), static_cast<float>(p.y)));
  std::vector<cv::Vec6f> list;
  subdiv.getTriangleList(list);

  const auto index_of = [&](float x, float y) {
    int best = -1;
    double best_distance = 1e-3;  // Subdiv2D hands back the float copies of our points
    for (int i = 0; i < static_cast<int>(points.size()); ++i) {
      const double distance = std::hypot(points[i].x - x, points[i].y - y);
      if (distance < best_distance) best = i, best_distance = distance;
    }
    return best;  // -1: one of Subdiv2D's virtual outer vertices
  };
  std::vector<std::array<int, 3>> triangles;
  for (const auto& t : list) {
    const std::array<int, 3> tri{index_of(t[0], t[1]), index_of(t[2], t[3]), index_of(t[4], t[5])};
    if (std::ranges::all_of(tri, [](int i) { return i >= 0; })) triangles.push_back(tri);
  }
  return triangles;
}

// Writes into (map_x, map_y), for every pixel inside the target triangle, where it comes
// from in the source triangle: the backward map of a piecewise-affine warp.
void rasterize_backward_map(const std::array<cv::Point2d, 3>& source, const std::array<cv::Point2d, 3>& target,
                            cv::Mat& map_x, cv::Mat& map_y) {
  const double area = signed_area(target[0], target[1], target[2]);
  if (std::abs(area) < 1e-9) return;  // collapsed (closed lips): covers no pixel
  const cv::Point2f src[3] = {source[0], source[1], source[2]};
  const cv::Point2f dst[3] = {target[0], target[1], target[2]};
  const cv::Matx23d to_source = cv::getAffineTransform(dst, src);

  const int x0 = std::max(0, static_cast<int>(std::floor(std::min({target[0].x, target[1].x, target[2].x}))));
  const int x1 =
      std::min(map_x.cols - 1, static_cast<int>(std::ceil(std::max({target[0].x, target[1].x, target[2].x}))));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min({target[0].y, target[1].y, target[2].y}))));
  const int y1 =
      std::min(map_x.rows - 1, static_cast<int>(std::ceil(std::max({target[0].y, target[1].y, target[2].y}))));
  constexpr double kEdgeTolerance = 1e-6;  // pixels on a shared edge belong to both triangles
  for (int y = y0; y <= y1; ++y) {
    auto* mx = map_x.ptr<float>(y);
    auto* my = map_y.ptr<float>(y);
    for (int x = x0; x <= x1; ++x) {
      const cv::Point2d p(x, y);
      const double b0 = signed_area(p, target[1], target[2]) / area;
      const double b1 = signed_area(target[0], p, target[2]) / area;
      const double b2 = 1 - b0 - b1;
      if (b0 < -kEdgeTolerance || b1 < -kEdgeTolerance || b2 < -kEdgeTolerance) continue;
      mx[x] = static_cast<float>(to_source(0, 0) * x + to_source(0, 1) * y + to_source(0, 2));
      my[x] = static_cast<float>(to_source(1, 0) * x + to_source(1, 1) * y + to_source(1, 2));
    }
  }
}

std::vector<cv::Point> polygon(const Landmarks2D& landmarks, int first, int last) {
  std::vector<cv::Point> points;
  for (int i = first; i <= last; ++i) points.emplace_back(cvRound(landmarks(0, i)), cvRound(landmarks(1, i)));
  return points;
}

// Teeth between the photo's parted lips would still show at the corners of the closed
// mouth, because the inner-lip landmarks sit a little inside the lips' edge. The inner-lip
// polygon, grown by a few percent of d, is repainted from the surrounding lip pixels by
// normalised convolution (Knutsson & Westin, "Normalized and Differential Convolution",
// CVPR 1993): the upper lip's colour near the upper lip, the lower's near the lower.
void paint_over_teeth(const Landmarks2D& photo, double d, cv::Mat& face) {
  cv::Mat teeth(face.size(), CV_8UC1, cv::Scalar(0));
  cv::fillPoly(teeth, std::vector{polygon(photo, ibug::kInnerCornerRight, kNumLandmarks - 1)}, cv::Scalar(255));
  const int grow = std::max(1, cvRound(0.06 * d));
  cv::dilate(teeth, teeth, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * grow + 1, 2 * grow + 1}));

  cv::Mat lips(face.size(), CV_8UC1, cv::Scalar(0));
  cv::fillPoly(lips, std::vector{polygon(photo, ibug::kMouthCornerRight, ibug::kInnerCornerRight - 1)},
               cv::Scalar(255));
  lips.setTo(0, teeth);
  const auto as_weights = [](const cv::Mat& mask) {
    cv::Mat weight;
    mask.convertTo(weight, CV_32F, 1 / 255.0);
    cv::merge(std::vector{weight, weight, weight}, weight);
    return weight;
  };
  cv::Mat colour;
  face.convertTo(colour, CV_32FC3);
  cv::Mat weight = as_weights(lips);
  cv::Mat weighted = colour.mul(weight);
  const double reach = std::max(1.0, 0.15 * d);
  cv::GaussianBlur(weighted, weighted, {}, reach);
  cv::GaussianBlur(weight, weight, {}, reach);
  const cv::Mat fill = weighted / (weight + cv::Scalar::all(1e-6));

  cv::GaussianBlur(teeth, teeth, {}, std::max(0.5, 0.03 * d));
  const cv::Mat alpha = as_weights(teeth);
  const cv::Mat blended = colour.mul(cv::Scalar::all(1) - alpha) + fill.mul(alpha);
  blended.convertTo(face, CV_8UC3);
}

// Closed Catmull-Rom spline through the inner-lip ring (Catmull & Rom, "A Class of Local
// Interpolating Splines", 1974): a mouth opening is curved, not the 8-gon of its landmarks.
// Points carry 3 fractional bits for fillPoly's sub-pixel drawing.
std::vector<cv::Point> smooth_ring(const std::vector<Vec2>& ring) {
  constexpr int kSamplesPerSegment = 8;
  const auto n = ring.size();
  std::vector<cv::Point> curve;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2& p0 = ring[(i + n - 1) % n];
    const Vec2& p1 = ring[i];
    const Vec2& p2 = ring[(i + 1) % n];
    const Vec2& p3 = ring[(i + 2) % n];
    for (int k = 0; k < kSamplesPerSegment; ++k) {
      const double t = static_cast<double>(k) / kSamplesPerSegment, t2 = t * t, t3 = t2 * t;
      const Vec2 p =
          0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2 + (3 * p1 - p0 - 3 * p2 + p3) * t3);
      curve.emplace_back(cvRound(p.x() * 8), cvRound(p.y() * 8));
    }
  }
  return curve;
}

// The open mouth: the inner lip ring filled with a dark red cavity that turns almost
// black towards its middle, with soft edges like a real mouth's shading.
void paint_mouth_cavity(const Landmarks2D& target, double d, cv::Mat& frame) {
  std::vector<Vec2> ring, core;
  for (int i = ibug::kInnerCornerRight; i < kNumLandmarks; ++i) ring.push_back(point(target, i));
  Vec2 centre = Vec2::Zero();
  for (const auto& p : ring) centre += p;
  centre /= static_cast<double>(ring.size());
  for (const auto& p : ring) core.push_back(centre + 0.5 * (p - centre));

  cv::Mat cavity(frame.size(), CV_8UC1, cv::Scalar(0));
  cv::Mat depth(frame.size(), CV_8UC1, cv::Scalar(0));
  cv::fillPoly(cavity, std::vector{smooth_ring(ring)}, cv::Scalar(255), cv::LINE_AA, 3);
  cv::fillPoly(depth, std::vector{smooth_ring(core)}, cv::Scalar(255), cv::LINE_AA, 3);
  const double edge_sigma = std::max(0.6, 0.015 * d);
  cv::GaussianBlur(cavity, cavity, {}, edge_sigma);
  cv::GaussianBlur(depth, depth, {}, 4 * edge_sigma);

  const cv::Vec3f lip_shadow(38, 36, 82), throat(12, 11, 22);  // BGR
  for (int y = 0; y < frame.rows; ++y) {
    const auto* a = cavity.ptr<std::uint8_t>(y);
    const auto* t = depth.ptr<std::uint8_t>(y);
    auto* px = frame.ptr<cv::Vec3b>(y);
    for (int x = 0; x < frame.cols; ++x) {
      if (a[x] == 0) continue;
      const float alpha = a[x] / 255.0f, deep = t[x] / 255.0f;
      const cv::Vec3f colour = lip_shadow * (1 - deep) + throat * deep;
      const cv::Vec3f mixed = cv::Vec3f(px[x]) * (1 - alpha) + colour * alpha;
      px[x] = cv::Vec3b(cv::saturate_cast<std::uint8_t>(mixed[0]), cv::saturate_cast<std::uint8_t>(mixed[1]),
                        cv::saturate_cast<std::uint8_t>(mixed[2]));
    }
  }
}

}  // namespace

std::vector<MouthPose> scripted_trajectory(double fps) {
  if (!(fps > 0)) throw std::invalid_argument("scripted_trajectory: the frame rate must be positive");
  const double duration = std::end(kScript)[-1].time_s;
  const auto frames = static_cast<int>(std::floor(duration * fps)) + 1;
  std::vector<MouthPose> poses;
  poses.reserve(frames);
  std::size_t k = 0;
  for (int f = 0; f < frames; ++f) {
    const double t = f / fps;
    while (k + 2 < std::size(kScript) && kScript[k + 1].time_s <= t) ++k;
    const Keyframe& a = kScript[k];
    const Keyframe& b = kScript[k + 1];
    poses.push_back(interpolate(a.pose, b.pose, std::clamp((t - a.time_s) / (b.time_s - a.time_s), 0.0, 1.0)));
  }
  return poses;
}

Landmarks2D close_inner_lips(const Landmarks2D& landmarks) {
  Landmarks2D closed = landmarks;
  // Facing pairs of the inner lip ring: (61, 67), (62, 66), (63, 65).
  for (const auto& [top, bottom] : {std::pair{61, 67}, std::pair{62, 66}, std::pair{63, 65}}) {
    const Vec2 middle = (point(landmarks, top) + point(landmarks, bottom)) / 2;
    closed.col(top) = middle;
    closed.col(bottom) = middle;
  }
  return closed;
}

Landmarks2D pose_mouth(const Landmarks2D& neutral, const MouthPose& pose) {
  const double d = normaliser(neutral);
  const Vec2 u = (point(neutral, ibug::kLeftEyeOuter) - point(neutral, ibug::kRightEyeOuter)).normalized();
  const Vec2 v(-u.y(), u.x());  // image y grows downwards, so this points down the face
  const Vec2 mouth_centre = (point(neutral, ibug::kMouthCornerRight) + point(neutral, ibug::kMouthCornerLeft)) / 2;
  Landmarks2D moved = neutral;
  for (int i = 0; i < kNumLandmarks; ++i) {
    const double across = (point(neutral, i) - mouth_centre).dot(u) / d;
    const Vec2 delta = displacement(i, across, pose);
    moved.col(i) += d * (delta.x() * u + delta.y() * v);
  }
  return moved;
}

TalkingFace::TalkingFace(const cv::Mat& portrait, const Landmarks2D& landmarks, const TalkingFaceOptions& options) {
  if (portrait.empty() || portrait.type() != CV_8UC3)
    throw std::invalid_argument("TalkingFace: the portrait must be a non-empty 8-bit BGR image");
  const Vec2 low = landmarks.rowwise().minCoeff();
  const Vec2 high = landmarks.rowwise().maxCoeff();
  if (!landmarks.allFinite() || (high - low).minCoeff() < 4 || normaliser(landmarks) < 1)
    throw std::invalid_argument("TalkingFace: the landmarks do not describe a face");

  // Crop and upscale in one resampling: landmark box centred, face_height_px tall.
  const double scale = options.face_height_px / (high.y() - low.y());
  const Vec2 centre = (low + high) / 2;
  const cv::Matx23d to_frame(scale, 0, options.frame_size.width / 2.0 - scale * centre.x(),  //
                             0, scale, options.frame_size.height / 2.0 - scale * centre.y());
  cv::warpAffine(portrait, face_, to_frame, options.frame_size, cv::INTER_CUBIC, cv::BORDER_REPLICATE);
  photo_landmarks_ = (scale * landmarks).colwise() + Vec2(to_frame(0, 2), to_frame(1, 2));
  paint_over_teeth(photo_landmarks_, normaliser(photo_landmarks_), face_);
  neutral_ = close_inner_lips(photo_landmarks_);

  anchors_ = make_anchors(photo_landmarks_, options.frame_size);
  std::vector<cv::Point2d> sources;
  for (int i = 0; i < kNumLandmarks; ++i) sources.push_back(to_cv(point(photo_landmarks_, i)));
  sources.insert(sources.end(), anchors_.begin(), anchors_.end());
  triangles_ = triangulate(sources, options.frame_size);
}

std::vector<cv::Point2d> TalkingFace::control_points(const Landmarks2D& target) const {
  std::vector<cv::Point2d> points;
  points.reserve(kNumLandmarks + anchors_.size());
  for (int i = 0; i < kNumLandmarks; ++i) points.push_back(to_cv(point(target, i)));
  points.insert(points.end(), anchors_.begin(), anchors_.end());
  return points;
}

cv::Mat TalkingFace::render(const Landmarks2D& target) const {
  // Identity everywhere, then each moved triangle maps back into the photo.
  cv::Mat map_x(face_.size(), CV_32FC1), map_y(face_.size(), CV_32FC1);
  for (int y = 0; y < face_.rows; ++y) {
    for (int x = 0; x < face_.cols; ++x) {
      map_x.at<float>(y, x) = static_cast<float>(x);
      map_y.at<float>(y, x) = static_cast<float>(y);
    }
  }
  const auto source = control_points(photo_landmarks_);
  const auto destination = control_points(target);
  for (const auto& [a, b, c] : triangles_) {
    if (source[a] == destination[a] && source[b] == destination[b] && source[c] == destination[c]) continue;
    rasterize_backward_map({source[a], source[b], source[c]}, {destination[a], destination[b], destination[c]}, map_x,
                           map_y);
  }
  cv::Mat frame;
  cv::remap(face_, frame, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  paint_mouth_cavity(target, normaliser(target), frame);
  return frame;
}

TalkingFaceFrame TalkingFace::frame(const MouthPose& pose) const {
  TalkingFaceFrame frame;
  frame.landmarks = landmarks(pose);
  frame.image = render(frame.landmarks);
  frame.truth = mouth_ratios(frame.landmarks);
  return frame;
}

}  // namespace lipdrive
