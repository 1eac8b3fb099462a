#include "sim/synthetic_head.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>
#include <stdexcept>

namespace lipdrive {
namespace {

// Proportions: adult means from Farkas, "Anthropometry of the Head and Face" (2nd ed.,
// 1994), rounded. The nasion is the origin.
constexpr float kStomionY = -74;         // n–sn 53 mm + sn–sto 21 mm
constexpr float kInnerCornerX = 23;      // where the lips part; the commissure is 2 mm further out
constexpr float kMouthHalfWidth = 25;    // ch–ch 50 mm
constexpr float kUpperVermilion = 8.5f;  // ls–sto ≈ 8–9 mm
constexpr float kLowerVermilion = 9.5f;  // sto–li ≈ 9–10 mm
constexpr float kEyeCentreX = 30.5f;     // midway between en (en–en 32 mm) and ex (ex–ex 90 mm)
constexpr float kEyeCentreY = -9;
constexpr float kEyeHalfWidth = 14.5f;  // ex–en ≈ 29 mm
constexpr float kEyeHalfHeight = 5.0f;  // palpebral fissure height ≈ 10 mm
constexpr float kMaxSideAngle = 85 * std::numbers::pi_v<float> / 180;
// Temporomandibular joint, just in front of the tragus (the hinge of the jaw rotation).
constexpr float kHingeY = -25, kHingeZ = -75;

float smoothstep(float edge0, float edge1, float x) {
  const float t = std::clamp((x - edge0) / (edge1 - edge0), 0.0f, 1.0f);
  return t * t * (3 - 2 * t);
}

/// exp(-(u² + v²)): a smooth bump with radii 1 in the normalised coordinates u, v.
float bump(float u, float v) { return std::exp(-(u * u + v * v)); }

struct Knot {
  float at;
  float value;
};

/// Cubic Hermite interpolation with Catmull–Rom tangents over knots sorted by `at`;
/// constant beyond the ends. Smooth, so the shaded surface shows no creases.
float interpolate(std::span<const Knot> knots, float at) {
  if (at <= knots.front().at) return knots.front().value;
  if (at >= knots.back().at) return knots.back().value;
  std::size_t i = 0;
  while (knots[i + 1].at < at) ++i;
  const auto tangent = [&](std::size_t k) {
    const std::size_t lo = k == 0 ? 0 : k - 1, hi = std::min(k + 1, knots.size() - 1);
    return (knots[hi].value - knots[lo].value) / (knots[hi].at - knots[lo].at);
  };
  const float h = knots[i + 1].at - knots[i].at;
  const float t = (at - knots[i].at) / h;
  const float t2 = t * t, t3 = t2 * t;
  return (2 * t3 - 3 * t2 + 1) * knots[i].value + (t3 - 2 * t2 + t) * h * tangent(i) +
         (-2 * t3 + 3 * t2) * knots[i + 1].value + (t3 - t2) * h * tangent(i + 1);
}

// ---------------------------------------------------------------------------------
// Neutral geometry. The face is swept from a midline profile: each row is a point of
// the sagittal profile (y, z) with an elliptical cross-section (half-width, depth), and
// local features (brows, eyes, nose, lips, cheekbones) are added along z.

struct ProfilePoint {
  float y, z, half_width, depth;
};

// Top of the forehead, over the brows, nose and lips, chin, then back under the jaw.
// Base profile only: the nose and the lip volume are features added on top.
constexpr ProfilePoint kProfile[] = {
    {72, -16, 62, 52},   {52, -5, 65, 58},    {32, 1, 67, 62},    {14, 3, 68, 64},     {0, 1, 69, 66},
    {-20, 2, 70, 70},    {-40, 3, 70, 72},    {-53, 4, 68, 72},   {-64, 4.5f, 65, 70}, {-74, 4, 62, 68},
    {-84, 2.5f, 59, 66}, {-95, 0, 56, 62},    {-106, -1, 52, 56}, {-116, -4, 47, 50},  {-122, -12, 45, 44},
    {-126, -26, 45, 34}, {-127, -38, 45, 26},
};
constexpr int kGnathionKnot = 13;  // rows past this knot are under the chin

/// Catmull–Rom through kProfile; t in [0, n-1] (knot i at t = i).
ProfilePoint profile_at(float t) {
  constexpr int n = static_cast<int>(std::size(kProfile));
  const int i = std::clamp(static_cast<int>(t), 0, n - 2);
  const float s = t - i;
  const auto& p0 = kProfile[std::max(i - 1, 0)];
  const auto& p1 = kProfile[i];
  const auto& p2 = kProfile[i + 1];
  const auto& p3 = kProfile[std::min(i + 2, n - 1)];
  const auto cr = [s](float a, float b, float c, float d) {
    return 0.5f * (2 * b + (c - a) * s + (2 * a - 5 * b + 4 * c - d) * s * s + (3 * b - a - 3 * c + d) * s * s * s);
  };
  return {cr(p0.y, p1.y, p2.y, p3.y), cr(p0.z, p1.z, p2.z, p3.z),
          cr(p0.half_width, p1.half_width, p2.half_width, p3.half_width), cr(p0.depth, p1.depth, p2.depth, p3.depth)};
}

/// Nose: a ridge whose height over the base profile rises from the nasion to the tip
/// (pronasale, 43 mm below n, ≈ 20 mm in front of the subnasale) and falls to the
/// subnasale; nose width al–al ≈ 34 mm (Farkas).
float nose(float x, float y) {
  constexpr Knot kHeight[] = {{-56, 0},  {-53, 1},  {-50, 7},    {-47, 15}, {-43, 19},
                              {-38, 17}, {-27, 12}, {-12, 6.5f}, {0, 1.5f}, {8, 0}};
  constexpr Knot kHalfWidth[] = {{-53, 9}, {-47, 11}, {-42, 9}, {-35, 7}, {-20, 6}, {0, 6}, {8, 7}};
  const float height = interpolate(kHeight, y);
  const float u = x / interpolate(kHalfWidth, y);
  const float alae = 6 * bump((std::abs(x) - 12.5f) / 5.5f, (y + 48) / 5);  // wings beside the tip
  return height * std::exp(-1.4f * u * u) + alae;
}

/// Brow ridges, eye sockets with the eyeball and lids inside, cheekbones.
float upper_face(float x, float y) {
  const float ax = std::abs(x);
  const float brow = 4 * bump((ax - 31) / 20, (y - 13) / 7);
  const float socket = -8 * bump((ax - kEyeCentreX) / 18, (y - kEyeCentreY + 1) / 11);
  const float r = std::hypot((ax - kEyeCentreX) / kEyeHalfWidth, (y - kEyeCentreY) / kEyeHalfHeight);
  // The eyeball shows through the fissure a step behind the lid margins.
  const float eyeball = r < 1 ? 3 * std::sqrt(1 - r * r) - 1.5f : 0;
  const float lids = 2 * std::exp(-std::pow((r - 1.1f) / 0.25f, 2.0f));
  const float lid_crease = y > kEyeCentreY ? -1.2f * std::exp(-std::pow((r - 1.9f) / 0.3f, 2.0f)) : 0;
  const float cheekbone = 5 * bump((ax - 46) / 17, (y + 30) / 14);
  return brow + socket + eyeball + lids + lid_crease + cheekbone;
}

/// The chin (mental protuberance) and the labiomental fold above it.
float chin(float x, float y) { return 4.5f * bump(x / 17, (y + 106) / 9) - 1.5f * bump(x / 16, (y + 94) / 4); }

float upper_vermilion_height(float x) {
  const float u = x / kMouthHalfWidth;
  return kUpperVermilion * std::sqrt(std::max(0.0f, 1 - u * u));
}
float lower_vermilion_height(float x) {
  const float u = x / kMouthHalfWidth;
  return kLowerVermilion * std::sqrt(std::max(0.0f, 1 - u * u));
}

/// Lip volume: each vermilion bulges forward between the stomion and its border,
/// tapering to nothing at the commissures; the lips meet in a shallow groove.
float lips(float x, float y) {
  const float u = x / kMouthHalfWidth;
  const float taper = std::pow(std::max(0.0f, 1 - u * u), 1.5f);
  if (taper == 0) return 0;
  const bool upper = y >= kStomionY;
  const float height = std::max(1.5f, upper ? upper_vermilion_height(x) : lower_vermilion_height(x));
  const float t = std::abs(y - kStomionY) / height;  // 0 at the stomion, 1 at the border
  const float bulge = (upper ? 4.5f : 5.0f) * std::exp(-std::pow((t - 0.5f) / 0.6f, 2.0f));
  const float border_roll = 0.6f * std::exp(-std::pow((t - 1) / 0.15f, 2.0f));
  const float groove = -1.5f * std::exp(-std::pow(t / 0.3f, 2.0f));
  return taper * (bulge + border_roll + groove);
}

/// The surface point of profile parameter t and side angle theta (0 = midline).
Eigen::Vector3f surface_point(float t, float theta) {
  const ProfilePoint p = profile_at(t);
  const float x = p.half_width * std::sin(theta);
  // The jaw line rises from the chin towards the gonion at the sides (a smooth ramp
  // below the mouth, so the rows never fold over each other).
  const float s = std::sin(theta), below = -85 - p.y;
  const float y = p.y + 0.6f * 0.5f * (below + std::sqrt(below * below + 16)) * s * s;
  const float z = p.z - p.depth * (1 - std::cos(theta)) + nose(x, y) + upper_face(x, y) + lips(x, y) + chin(x, y);
  return {x, y, z};
}

// ---------------------------------------------------------------------------------
// Sampling: rows along the profile, columns in side angle; denser where the
// landmarks are (mouth, eyes).

float row_spacing(float y) {
  const float mid_face = 1 - smoothstep(15, 30, std::abs(y + 40) - 45);  // brows to chin
  const float mouth = 1 - smoothstep(14, 22, std::abs(y - kStomionY));
  const float eyes = 1 - smoothstep(8, 14, std::abs(y - kEyeCentreY));
  return 5.0f - std::max({2.4f * mid_face, 3.6f * mouth, 3.4f * eyes});
}

/// Profile parameters of the rows, top to bottom, one row exactly at the stomion.
std::vector<float> row_parameters() {
  constexpr int kSamples = 4000;
  const float t_end = static_cast<float>(std::size(kProfile) - 1);
  std::vector<float> ts(kSamples + 1), arc(kSamples + 1, 0);
  for (int i = 0; i <= kSamples; ++i) {
    ts[i] = t_end * i / kSamples;
    if (i > 0) {
      const ProfilePoint a = profile_at(ts[i - 1]), b = profile_at(ts[i]);
      arc[i] = arc[i - 1] + std::hypot(b.y - a.y, b.z - a.z);
    }
  }
  std::vector<float> rows;
  std::size_t i = 0;
  for (float s = 0; s <= arc.back(); s += row_spacing(profile_at(ts[i]).y)) {
    while (i < arc.size() - 1 && arc[i] < s) ++i;
    rows.push_back(ts[i]);
  }
  // Snap the row nearest the stomion onto it (y decreases monotonically along t).
  const auto nearest = std::min_element(rows.begin(), rows.end(), [](float a, float b) {
    return std::abs(profile_at(a).y - kStomionY) < std::abs(profile_at(b).y - kStomionY);
  });
  float lo = 0, hi = t_end;
  for (int k = 0; k < 40; ++k) {
    const float mid = 0.5f * (lo + hi);
    (profile_at(mid).y > kStomionY ? lo : hi) = mid;
  }
  *nearest = 0.5f * (lo + hi);
  return rows;
}

/// Side angles of the columns, symmetric with one at the midline and one exactly at
/// each inner mouth corner and each commissure (measured on the stomion row).
std::vector<float> column_angles(const ProfilePoint& stomion_row) {
  const float a = stomion_row.half_width, b = stomion_row.depth;
  std::vector<float> half{0};
  constexpr int kMouthSteps = 12;
  for (int k = 1; k <= kMouthSteps; ++k) half.push_back(std::asin(kInnerCornerX * k / kMouthSteps / a));
  half.push_back(std::asin(kMouthHalfWidth / a));
  while (half.back() < kMaxSideAngle) {
    const float theta = half.back();
    const float x = a * std::sin(theta);
    const float spacing = 2 + 3 * smoothstep(kMouthHalfWidth, 50, x);
    const float arc_rate = std::hypot(a * std::cos(theta), b * std::sin(theta));
    half.push_back(std::min(kMaxSideAngle, theta + spacing / arc_rate));
  }
  std::vector<float> columns;
  for (auto it = half.rbegin(); it != half.rend(); ++it) columns.push_back(-*it);
  columns.insert(columns.end(), half.begin() + 1, half.end());
  return columns;
}

// ---------------------------------------------------------------------------------
// Deformation weights: how much each vertex follows each articulator.

enum class LipSide { Upper, Lower, Either };

/// Share of the lower lip/jaw at a point: 0 above the mouth, 1 below it. Along the
/// slit the two copies of a vertex start from different shares (so the lips part
/// with a parabolic opening closing at the corners); `reach` is how far from the
/// mouth line the share takes to settle, growing beyond the corners where the
/// skin stretches instead of parting.
float lower_share(float x, float y, LipSide side, float reach) {
  const float corner = std::min(1.0f, (x / kInnerCornerX) * (x / kInnerCornerX));
  const float at_top = side == LipSide::Lower ? 1 - 0.5f * corner : 0.5f * corner;
  const float at_bottom = side == LipSide::Upper ? 0.5f * corner : 1 - 0.5f * corner;
  const float spread = reach * (1 + 0.1f * std::max(0.0f, std::abs(x) - kInnerCornerX));
  if (y > kStomionY) return at_top * (1 - smoothstep(0, spread, y - kStomionY));
  if (y < kStomionY) return at_bottom + (1 - at_bottom) * smoothstep(0, spread, kStomionY - y);
  return side == LipSide::Upper ? at_top : at_bottom;
}

/// ≈1 on the lips, fading to 0 within ~10 mm around the vermilion (a flat-topped
/// super-Gaussian: no edges for the shading to show).
float lip_region(float x, float y) {
  const float u = x / 32, v = (y - kStomionY) / 14;
  return std::exp(-std::pow(u * u, 4.0f) - v * v * v * v);
}

/// The lips and the skin the orbicularis oris drags along when rounding, spreading
/// or protruding: broad and smooth, reaching the cheeks and the chin.
float perioral_region(float x, float y) {
  const float u = x / 40, v = (y - kStomionY) / 20;
  return std::exp(-u * u * u * u - v * v);
}

struct VertexWeights {
  float jaw;        // follows the mandible
  float lip;        // follows the lip alone (raise, drop, roll, tuck)
  float perioral;   // follows rounding, spread and protrusion
  float lower_lip;  // 0 = upper lip, 1 = lower lip (within the lip region)
};

VertexWeights weights_at(const Eigen::Vector3f& p, LipSide side) {
  return {lower_share(p.x(), p.y(), side, 14), lip_region(p.x(), p.y()), perioral_region(p.x(), p.y()),
          lower_share(p.x(), p.y(), side, 3)};
}

// ---------------------------------------------------------------------------------
// The mesh.

struct NeutralHead {
  Eigen::Matrix3Xf vertices;
  std::vector<VertexWeights> weights;
  std::vector<Triangle> triangles;
  std::array<std::int32_t, kNumLandmarks> landmark_vertex;
};

constexpr int kCavityRingPoints = 11;

/// Mouth cavity behind the slit: per slit column a loop from the upper lip's inner
/// edge back over the palate and forward along the floor to the lower lip's inner edge.
Eigen::Vector3f cavity_point(const Eigen::Vector3f& stomion, float angle) {
  const float open = std::sqrt(std::max(0.0f, 1 - std::pow(stomion.x() / kInnerCornerX, 2.0f)));
  const float half_height = 10 * open, half_depth = 14 * open;
  const float back = (1 - std::cos(angle)) / 2;
  return {stomion.x() * (1 - 0.2f * back), stomion.y() + half_height * std::sin(angle),
          stomion.z() - 2 * half_depth * back};
}

/// The unused vertex nearest to `target` in (x, y) among `candidates`.
std::int32_t nearest_vertex(const Eigen::Matrix3Xf& vertices, const std::vector<std::int32_t>& candidates,
                            const Eigen::Vector2f& target, const std::vector<std::int32_t>& taken) {
  std::int32_t best = -1;
  float best_distance = std::numeric_limits<float>::max();
  for (std::int32_t v : candidates) {
    if (std::find(taken.begin(), taken.end(), v) != taken.end()) continue;
    const float d = (vertices.col(v).head<2>() - target).squaredNorm();
    if (d < best_distance) best_distance = d, best = v;
  }
  return best;
}

NeutralHead build_neutral_head() {
  const std::vector<float> rows = row_parameters();
  const int stomion_row = static_cast<int>(std::min_element(rows.begin(), rows.end(),
                                                            [](float a, float b) {
                                                              return std::abs(profile_at(a).y - kStomionY) <
                                                                     std::abs(profile_at(b).y - kStomionY);
                                                            }) -
                                           rows.begin());
  const std::vector<float> columns = column_angles(profile_at(rows[stomion_row]));
  const int num_rows = static_cast<int>(rows.size()), num_columns = static_cast<int>(columns.size());
  const int midline = num_columns / 2;
  const int right_corner = midline - 12, left_corner = midline + 12;  // inner corners (kMouthSteps)
  const auto in_slit = [&](int c) { return c > right_corner && c < left_corner; };

  NeutralHead head;
  std::vector<Eigen::Vector3f> points;
  std::vector<VertexWeights> weights;
  for (int r = 0; r < num_rows; ++r)
    for (int c = 0; c < num_columns; ++c) {
      points.push_back(surface_point(rows[r], columns[c]));
      const LipSide side = r == stomion_row && in_slit(c) ? LipSide::Upper : LipSide::Either;
      weights.push_back(weights_at(points.back(), side));
    }
  const auto grid = [&](int r, int c) { return static_cast<std::uint32_t>(r * num_columns + c); };

  // The lower lip's own copy of the slit vertices.
  std::vector<std::uint32_t> lower_copy(num_columns);
  for (int c = 0; c < num_columns; ++c) {
    if (!in_slit(c)) {
      lower_copy[c] = grid(stomion_row, c);
      continue;
    }
    lower_copy[c] = static_cast<std::uint32_t>(points.size());
    points.push_back(points[grid(stomion_row, c)]);
    weights.push_back(weights_at(points.back(), LipSide::Lower));
  }
  const auto vertex_below = [&](int r, int c) { return r == stomion_row ? lower_copy[c] : grid(r, c); };

  // Skin: two counter-clockwise triangles (seen from the front) per grid cell.
  for (int r = 0; r + 1 < num_rows; ++r)
    for (int c = 0; c + 1 < num_columns; ++c) {
      const std::uint32_t top_left = vertex_below(r, c), top_right = vertex_below(r, c + 1);
      const std::uint32_t bottom_left = grid(r + 1, c), bottom_right = grid(r + 1, c + 1);
      head.triangles.push_back({bottom_left, bottom_right, top_right});
      head.triangles.push_back({bottom_left, top_right, top_left});
    }

  // Cavity: rings from the upper copy to the lower copy; wound to face into the
  // tissue, so through the open mouth the renderer sees its back faces (dark).
  std::vector<std::vector<std::uint32_t>> rings;
  for (int c = right_corner; c <= left_corner; ++c) {
    std::vector<std::uint32_t> ring{grid(stomion_row, c)};
    for (int k = 1; k <= kCavityRingPoints; ++k) {
      if (!in_slit(c)) {
        ring.push_back(grid(stomion_row, c));
        continue;
      }
      const float along = static_cast<float>(k) / (kCavityRingPoints + 1);
      const Eigen::Vector3f stomion = points[grid(stomion_row, c)];
      ring.push_back(static_cast<std::uint32_t>(points.size()));
      points.push_back(cavity_point(stomion, 2 * std::numbers::pi_v<float> * along));
      // Upper half follows the upper jaw, lower half the mandible; deep points ignore the lips.
      const VertexWeights upper = weights[grid(stomion_row, c)], lower = weights[lower_copy[c]];
      const float depth_fade = std::exp(-std::pow((points.back() - stomion).norm() / 6, 2.0f));
      const float blend = smoothstep(0.3f, 0.7f, along);
      weights.push_back({upper.jaw + (lower.jaw - upper.jaw) * blend, upper.lip * depth_fade,
                         upper.perioral * depth_fade, upper.lower_lip + (lower.lower_lip - upper.lower_lip) * blend});
    }
    ring.push_back(lower_copy[c]);
    rings.push_back(std::move(ring));
  }
  for (std::size_t c = 0; c + 1 < rings.size(); ++c)
    for (std::size_t k = 0; k + 1 < rings[c].size(); ++k) {
      const std::uint32_t a = rings[c][k], b = rings[c + 1][k], d = rings[c][k + 1], e = rings[c + 1][k + 1];
      if (a != b && a != d && b != d) head.triangles.push_back({a, b, d});
      if (b != e && b != d && e != d) head.triangles.push_back({b, e, d});
    }

  head.vertices.resize(3, static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) head.vertices.col(static_cast<Eigen::Index>(i)) = points[i];
  head.weights = std::move(weights);

  // Landmarks. The mouth corners and the inner ring sit on known grid vertices; the
  // others are the nearest front-of-face vertex to their anthropometric position.
  auto& lm = head.landmark_vertex;
  lm.fill(-1);
  const auto column_at = [&](float x) {
    int best = 0;
    for (int c = 0; c < num_columns; ++c)
      if (std::abs(points[grid(stomion_row, c)].x() - x) < std::abs(points[grid(stomion_row, best)].x() - x)) best = c;
    return best;
  };
  const auto id = [](std::uint32_t v) { return static_cast<std::int32_t>(v); };
  lm[48] = id(grid(stomion_row, right_corner - 1));
  lm[54] = id(grid(stomion_row, left_corner + 1));
  lm[60] = id(grid(stomion_row, right_corner));
  lm[64] = id(grid(stomion_row, left_corner));
  constexpr float kInnerLipX[] = {-11.5f, 0, 11.5f};
  for (int k = 0; k < 3; ++k) {
    lm[61 + k] = id(grid(stomion_row, column_at(kInnerLipX[k])));
    lm[67 - k] = id(lower_copy[column_at(kInnerLipX[k])]);
  }

  std::vector<Eigen::Vector2f> targets(kNumLandmarks, Eigen::Vector2f::Zero());
  for (int k = 0; k <= 16; ++k) {  // jaw contour: an oval from ear level round the chin
    const float angle = std::numbers::pi_v<float> * (1 + k / 16.0f);
    targets[k] = {67 * std::cos(angle), -15 + 105 * std::sin(angle)};
  }
  constexpr float kBrowX[] = {-55, -45, -35, -24, -14};  // outer to inner, right brow
  constexpr float kBrowY[] = {11, 16, 18, 17.5f, 15};
  for (int k = 0; k < 5; ++k) {
    targets[17 + k] = {kBrowX[k], kBrowY[k]};
    targets[26 - k] = {-kBrowX[k], kBrowY[k]};
  }
  targets[27] = {0, 0};
  targets[28] = {0, -14};
  targets[29] = {0, -29};
  targets[30] = {0, -43};  // pronasale
  constexpr float kLowerNoseX[] = {-13, -7, 0, 7, 13};
  constexpr float kLowerNoseY[] = {-50, -52, -53, -52, -50};
  for (int k = 0; k < 5; ++k) targets[31 + k] = {kLowerNoseX[k], kLowerNoseY[k]};
  for (int k = 0; k < 6; ++k) {  // eyes: clockwise in the image from the left-most corner
    const float angle = std::numbers::pi_v<float> * (1 - k / 3.0f);
    const Eigen::Vector2f offset{kEyeHalfWidth * std::cos(angle), kEyeHalfHeight * std::sin(angle)};
    targets[36 + k] = Eigen::Vector2f{-kEyeCentreX, kEyeCentreY} + offset;  // from the outer corner
    targets[42 + k] = Eigen::Vector2f{kEyeCentreX, kEyeCentreY} + offset;   // from the inner corner
  }
  constexpr float kOuterLipX[] = {-16, -7.5f, 0, 7.5f, 16};
  for (int k = 0; k < 5; ++k) {
    targets[49 + k] = {kOuterLipX[k], kStomionY + upper_vermilion_height(kOuterLipX[k])};
    targets[59 - k] = {kOuterLipX[k], kStomionY - lower_vermilion_height(kOuterLipX[k])};
  }

  // Front of the face: rows down to the chin, front-facing side angles.
  std::vector<std::int32_t> front;
  for (int r = 0; r < num_rows; ++r)
    if (rows[r] <= kGnathionKnot + 0.5f)
      for (int c = 0; c < num_columns; ++c) front.push_back(id(grid(r, c)));
  std::vector<std::int32_t> taken(lm.begin(), lm.end());
  for (int i = 0; i < kNumLandmarks; ++i) {
    if (lm[i] >= 0) continue;
    lm[i] = nearest_vertex(head.vertices, front, targets[i], taken);
    taken.push_back(lm[i]);
  }
  return head;
}

// ---------------------------------------------------------------------------------
// Articulation.

/// One viseme at full intensity; intensity p scales every parameter by p. Each viseme
/// gets its own mix of these articulators, so no viseme is (nearly) a scaled copy of
/// another: a character's mouth shapes must stay tellable apart at every intensity from
/// the landmarks a front camera sees. Only the lower lip rolls: with an upper-lip roll
/// the fit explained a performer's thinner upper lip by rolling it in and opening the
/// jaw, so real closed lips read as parted (GRID bbaf2n: scaled height on "bin" 0.28
/// instead of 0.16).
struct Articulation {
  float jaw_degrees = 0;   // mandible rotation about the TMJ (opens the mouth)
  float rounding = 0;      // fraction by which the lips narrow towards the midline
  float protrusion = 0;    // mm the lips move forward
  float spread = 0;        // mm each corner moves outward (the risorius: the corners most)
  float corner_raise = 0;  // mm the corners rise (smile; negative: they sink)
  float upper_raise = 0;   // mm the whole upper lip rises
  float lower_drop = 0;    // mm the whole lower lip drops (beyond the jaw)
  float lower_square = 0;  // mm the lower lip drops beside the midline
  float lower_roll = 0;    // fraction of the lower vermilion rolled in (negative: turned out)
  float lower_tuck = 0;    // mm the lower lip moves back and up under the upper teeth
};

Articulation articulation(std::string_view viseme) {
  struct Entry {
    std::string_view name;
    Articulation a;
  };
  // jaw°, rounding, protrusion, spread, corner raise, upper raise, lower drop,
  // lower square, lower roll, lower tuck
  static const Entry kTable[] = {
      {"Aah", {12, 0.06f, 0, 0, 0, 1, 0, 0, 0, 0}},
      {"BigAah", {17, 0, 0, 3.5f, 0, 2, 0, 0, 0, 0}},
      {"B-M-P", {0, 0, 0.5f, 0, 0, 0, 0, 0, 0.9f, 0}},
      {"Ch-J-Sh", {3, 0.2f, 6, 0, 0, 2, 0, 3, -0.4f, 0}},
      {"D-S-T", {2, 0, 0, 4, 0, 3, 2.5f, 0, 0, 0}},
      {"Eee", {2, 0, 0, 7, 4, 1, 1, 0, 0, 0}},
      {"Eh", {9, 0, 0, 3, 0, 1, 0, 0, 0, 0}},
      {"F-V", {1.5f, 0, 0, 0, 0, 2.5f, 0, 0, 0.9f, 5}},
      {"i", {5, 0, 0, 5, 0, 2, 1.5f, 0, 0, 0}},
      {"K", {7, 0, 0, 1, -2.5f, 0, 0, 2.5f, 0, 0}},
      {"N", {3, 0, 1, 2, 2.5f, 0, 0, 0, 0, 0}},
      {"Oh", {11, 0.3f, 5, 0, 0, 0, 0, 0, -0.3f, 0}},
      {"Ooh-Q", {4, 0.42f, 7, 0, 0, 0, 0, 0, -0.4f, 0}},
      {"R", {3, 0.25f, 4, 0, -1.5f, 3, 0, 0, 0, 0}},
      {"Th", {4, 0, 0, 0, 0, 0.5f, 3.5f, 0, -0.6f, 0}},
      {"W", {2, 0.5f, 8, 0, 0, 0, 0, 0, 0.2f, 0}},
  };
  for (const auto& e : kTable)
    if (e.name == viseme) return e.a;
  throw std::invalid_argument("unknown viseme " + std::string(viseme));
}

Articulation scaled(const Articulation& a, float p) {
  return {a.jaw_degrees * p, a.rounding * p,   a.protrusion * p,   a.spread * p,     a.corner_raise * p,
          a.upper_raise * p, a.lower_drop * p, a.lower_square * p, a.lower_roll * p, a.lower_tuck * p};
}

/// The lips first (in the neutral frame), then the mandible carries the lower lip:
/// rotation about the TMJ hinge plus the condyle's forward glide during opening.
Eigen::Vector3f articulate(const Eigen::Vector3f& p, const VertexWeights& w, const Articulation& a) {
  Eigen::Vector3f q = p;
  const float u = std::clamp(p.x() / kMouthHalfWidth, -1.0f, 1.0f);
  const float upper = w.lip * (1 - w.lower_lip), lower = w.lip * w.lower_lip;
  const float from_stomion = p.y() - kStomionY;
  // The lower vermilion (and a little skin below it) rolls about the line where the lips
  // meet, which stays put: a roll moves the lip border, not the inner lip line.
  const float roll = a.lower_roll * lower * std::exp(-std::pow(from_stomion / 12, 4.0f));
  const float off_contact = 1 - std::exp(-std::pow(from_stomion / 4, 2.0f));
  const float beside_midline = 4 * u * u * (1 - u * u);  // 0 at the midline and the corners, 1 between
  q.x() += w.perioral * (-a.rounding * p.x() + a.spread * u * std::abs(u));
  q.y() += w.perioral * (0.25f * a.spread + a.corner_raise * u * u) * u * u + a.upper_raise * upper -
           (a.lower_drop + a.lower_square * beside_midline - 0.2f * a.lower_tuck) * lower - roll * from_stomion;
  q.z() += w.perioral * (a.protrusion * (1 - 0.4f * u * u) - 0.5f * a.spread * u * u) -
           a.lower_tuck * lower * (1 - 0.5f * u * u) - 3 * roll * off_contact;

  const float angle = w.jaw * a.jaw_degrees * std::numbers::pi_v<float> / 180;
  const Eigen::Vector3f hinge{q.x(), kHingeY, kHingeZ};
  const Eigen::Vector3f glide{0, -0.1f, 0.35f};  // mm per degree of opening
  return hinge + Eigen::AngleAxisf(angle, Eigen::Vector3f::UnitX()) * (q - hinge) + glide * (w.jaw * a.jaw_degrees);
}

Eigen::Matrix3Xf articulate_all(const NeutralHead& head, const Articulation& a) {
  Eigen::Matrix3Xf out(3, head.vertices.cols());
  for (Eigen::Index i = 0; i < head.vertices.cols(); ++i)
    out.col(i) = articulate(head.vertices.col(i), head.weights[static_cast<std::size_t>(i)], a);
  return out;
}

std::string pose_name(std::string_view viseme, int percent) {
  std::string digits = std::to_string(percent);
  return std::string(viseme) + "_" + std::string(3 - digits.size(), '0') + digits;
}

}  // namespace

SyntheticHead generate_synthetic_head(HeadPoseSet set) {
  const NeutralHead head = build_neutral_head();
  SyntheticHead out{head.triangles, head.landmark_vertex, {}};
  out.poses.push_back({"neutral", head.vertices});
  const int first_percent = set == HeadPoseSet::Full161 ? 10 : 100;
  for (std::string_view viseme : kVisemeNames)
    for (int percent = first_percent; percent <= 100; percent += 10)
      out.poses.push_back(
          {pose_name(viseme, percent), articulate_all(head, scaled(articulation(viseme), percent / 100.0f))});
  return out;
}

}  // namespace lipdrive
