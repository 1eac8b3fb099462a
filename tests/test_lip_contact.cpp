// Lip contact (core/lip_contact.hpp) on drawn mouths whose answer is known: sealed lips with
// the landmarks on them or lagging half open, a dark cavity, teeth hardly brighter than the
// lips; in colour, grey teeth no brighter than the lips and sealed lips whose shading looks like
// teeth in luma; a deep crease between sealed lips; at several resolutions and exposures; and
// the viseme transfer it feeds.
#include "allocation_counter.hpp"
#include "core/lip_contact.hpp"
#include "core/viseme_weights.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <vector>

namespace lipdrive {
namespace {

/// kGreyTeeth: teeth as bright as the lips and no line between them (luma shows nothing);
/// kShadedSeal: sealed lips with a bright band on the upper lip just above the line, which in
/// luma is the pattern of teeth (a blurred frame's lip shading); kDeepSeal: sealed lips meeting
/// in a crease about as dark and wide as GRID's (its darkness integral 0.034-0.055 d at the
/// scales drawn, GRID's 0.049 d; kSealed's 0.009-0.012 d).
enum class Inside { kSealed, kCavity, kTeeth, kGreyTeeth, kShadedSeal, kDeepSeal };

struct DrawnMouth {
  cv::Mat gray;
  cv::Mat cr;  // Cr at half size both ways (4:2:0): skin 128 + 12, lips 128 + 30, teeth 128 + 2
  Landmarks2D landmarks;
  double d = 0;
};

/// A face at `scale` (d = 40 px at scale 1) whose lips part by `opening` x d in the image, with
/// landmarks whose inner lips part by `landmark_opening` x d (the regression's lag).
DrawnMouth draw_mouth(Inside inside, double opening, double landmark_opening, double scale = 1.0, double gain = 1.0) {
  Landmarks2D p = Landmarks2D::Constant(120.0);
  const auto set = [&](int i, double x, double y) { p.col(i) << x, y; };
  set(36, 60, 100), set(39, 88, 100), set(42, 112, 100), set(45, 140, 100), set(30, 100, 140);
  const double d = 40, half_true = 0.5 * opening * d, half_lm = 0.5 * landmark_opening * d;
  // Outer lips: corners at y = 180, the upper lip 7 px thick at the middle, the lower 9 px,
  // both pushed apart by the opening.
  set(48, 76, 180), set(54, 124, 180);
  const double upper[5] = {175, 172, 173, 172, 175}, lower[5] = {186, 189, 190, 189, 186};
  for (int k = 0; k < 5; ++k) {
    set(49 + k, 84 + 8 * k, upper[k] - half_true);
    set(59 - k, 84 + 8 * k, lower[k] + half_true);
  }
  set(60, 80, 180), set(64, 120, 180);
  for (int k = 0; k < 3; ++k) {
    set(61 + k, 90 + 10 * k, 180 - half_lm);
    set(67 - k, 90 + 10 * k, 180 + half_lm);
  }
  // The true inner contour, which the landmarks may miss.
  std::vector<cv::Point> outer, gap;
  const auto pt = [&](double x, double y) { return cv::Point(cvRound(x * scale * 16), cvRound(y * scale * 16)); };
  for (int i = 48; i <= 59; ++i) outer.push_back(pt(p(0, i), p(1, i)));
  for (double x : {80.0, 90.0, 100.0, 110.0, 120.0}) gap.push_back(pt(x, 180 - (x == 80 || x == 120 ? 0 : half_true)));
  for (double x : {110.0, 100.0, 90.0}) gap.push_back(pt(x, 180 + half_true));

  const int line = std::max(1, cvRound(scale));
  cv::Mat image(cvRound(260 * scale), cvRound(200 * scale), CV_8UC1, cv::Scalar(150));
  cv::Mat cr(image.size(), CV_8UC1, cv::Scalar(140));
  cv::fillPoly(image, std::vector<std::vector<cv::Point>>{outer}, cv::Scalar(110), cv::LINE_AA, 4);
  cv::fillPoly(cr, std::vector<std::vector<cv::Point>>{outer}, cv::Scalar(158), cv::LINE_AA, 4);
  if (inside == Inside::kSealed || inside == Inside::kShadedSeal || inside == Inside::kDeepSeal) {
    if (inside == Inside::kShadedSeal)
      cv::line(image, pt(84, 177), pt(116, 177), cv::Scalar(150), 2 * line, cv::LINE_AA, 4);
    if (inside == Inside::kDeepSeal)
      cv::line(image, pt(80, 180), pt(120, 180), cv::Scalar(65), 3 * line, cv::LINE_AA, 4);
    else
      cv::line(image, pt(80, 180), pt(120, 180), cv::Scalar(80), line, cv::LINE_AA, 4);
    cv::line(cr, pt(80, 180), pt(120, 180), cv::Scalar(152), line, cv::LINE_AA, 4);  // the shadow's colour
  } else {
    const double luma = inside == Inside::kCavity ? 40 : inside == Inside::kTeeth ? 128 : 110;
    cv::fillPoly(image, std::vector<std::vector<cv::Point>>{gap}, cv::Scalar(luma), cv::LINE_AA, 4);
    cv::fillPoly(cr, std::vector<std::vector<cv::Point>>{gap}, cv::Scalar(inside == Inside::kCavity ? 136 : 130),
                 cv::LINE_AA, 4);
    if (inside == Inside::kTeeth)  // the dark line between upper and lower teeth
      cv::line(image, pt(84, 180), pt(116, 180), cv::Scalar(60), line, cv::LINE_AA, 4);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7 * scale);
  image.convertTo(image, CV_8UC1, gain);
  cv::GaussianBlur(cr, cr, cv::Size(0, 0), 0.7 * scale);
  cv::resize(cr, cr, cv::Size((image.cols + 1) / 2, (image.rows + 1) / 2), 0, 0, cv::INTER_AREA);
  return {image, cr, p * scale, d * scale};
}

TEST(LipContact, SealedLipsReadSealedEvenWhenTheLandmarksLagHalfOpen) {
  for (const double lag : {0.0, 0.1, 0.2}) {
    SCOPED_TRACE(::testing::Message() << "landmark opening " << lag << " d");
    const DrawnMouth m = draw_mouth(Inside::kSealed, 0, lag);
    const LipGap gap = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
    ASSERT_TRUE(gap.valid);
    EXPECT_LT(gap.darkness, 0.02);
    EXPECT_LT(gap.texture, 0.02);
    const double seal = seal_probability(gap, lag);
    EXPECT_GT(seal, 0.9);
    EXPECT_LT(fused_opening(lag, seal), 0.02);
  }
}

TEST(LipContact, ADarkCavityIsOpenAndMeasuredInUnitsOfD) {
  double previous_opening = 0, previous_darkness = 0;
  for (const double opening : {0.15, 0.25, 0.4}) {
    SCOPED_TRACE(::testing::Message() << "opening " << opening << " d");
    const DrawnMouth m = draw_mouth(Inside::kCavity, opening, opening);
    const LipGap gap = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
    ASSERT_TRUE(gap.valid);
    // Each further 1 d of cavity adds its contrast against the lips (luma 40 against 110) to
    // the darkness: the blur moves darkness along the profile, it does not add or remove any.
    if (previous_opening > 0) {
      EXPECT_NEAR(gap.darkness - previous_darkness, (1 - 40.0 / 110.0) * (opening - previous_opening), 0.01);
    }
    previous_opening = opening, previous_darkness = gap.darkness;
    const double seal = seal_probability(gap, opening);
    EXPECT_LT(seal, 0.05);
    EXPECT_NEAR(fused_opening(opening, seal), opening, 0.02);
  }
}

TEST(LipContact, TeethHardlyBrighterThanTheLipsStillPartThem) {
  const DrawnMouth m = draw_mouth(Inside::kTeeth, 0.2, 0.2);
  const LipGap gap = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
  ASSERT_TRUE(gap.valid);
  EXPECT_GT(gap.texture, 0.1);
  EXPECT_LT(seal_probability(gap, 0.2), 0.05);
}

TEST(LipContact, InColourGreyTeethAsBrightAsTheLipsPartThem) {
  const DrawnMouth m = draw_mouth(Inside::kGreyTeeth, 0.15, 0.15);
  const LipGap luma = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
  ASSERT_TRUE(luma.valid);
  EXPECT_FALSE(luma.colour);
  EXPECT_GT(seal_probability(luma, 0.15), 0.9) << "in luma alone the teeth are lips";
  const LipGap colour = measure_lip_gap(m.gray, m.cr, m.landmarks);
  ASSERT_TRUE(colour.valid);
  EXPECT_TRUE(colour.colour);
  EXPECT_NEAR(colour.lip_red, 30, 2);
  EXPECT_GT(colour.pallor, 0.05);
  EXPECT_LT(seal_probability(colour, 0.15), 0.05);
}

TEST(LipContact, InColourSealedLipsWhoseShadingLooksLikeTeethStaySealed) {
  // The landmarks' inner contours lag apart, so the region where the lips meet takes in the band.
  for (const double lag : {0.15, 0.2}) {
    SCOPED_TRACE(::testing::Message() << "landmark opening " << lag << " d");
    const DrawnMouth m = draw_mouth(Inside::kShadedSeal, 0, lag);
    const LipGap luma = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
    ASSERT_TRUE(luma.valid);
    EXPECT_LT(seal_probability(luma, lag), 0.5) << "in luma alone the shading reads as teeth";
    const LipGap colour = measure_lip_gap(m.gray, m.cr, m.landmarks);
    ASSERT_TRUE(colour.colour);
    EXPECT_LT(colour.pallor, 0.01);
    EXPECT_GT(seal_probability(colour, lag), 0.9);
  }
}

TEST(LipContact, LipsWithoutColourFallBackToTheLuma) {
  const DrawnMouth m = draw_mouth(Inside::kTeeth, 0.2, 0.2);
  const cv::Mat grey(m.cr.size(), CV_8UC1, cv::Scalar(129));  // a camera whose colour is all but gone
  const LipGap gap = measure_lip_gap(m.gray, grey, m.landmarks);
  ASSERT_TRUE(gap.valid);
  EXPECT_FALSE(gap.colour);
  EXPECT_EQ(gap.pallor, 0);
  EXPECT_EQ(seal_probability(gap, 0.2), seal_probability(measure_lip_gap(m.gray, cv::Mat(), m.landmarks), 0.2));
}

// The darkness is over d, and so is the line's own (the crease where the lips meet is the face's):
// a sealed mouth magnified four times reads sealed, as a head-mounted camera's large face or a
// video upscaled to HD must (with the line's allowance in pixels, the deep crease at four times
// the size read apart).
TEST(LipContact, TheSameMouthReadsTheSameAtAnyResolutionAndExposure) {
  for (const Inside inside : {Inside::kSealed, Inside::kDeepSeal, Inside::kCavity, Inside::kTeeth}) {
    const bool sealed = inside == Inside::kSealed || inside == Inside::kDeepSeal;
    const double opening = sealed ? 0.0 : 0.25;
    const DrawnMouth reference = draw_mouth(inside, opening, opening + 0.1);
    const LipGap expected = measure_lip_gap(reference.gray, cv::Mat(), reference.landmarks);
    const double expected_seal = seal_probability(expected, opening + 0.1);
    if (sealed) {
      EXPECT_GT(expected_seal, 0.9);
    }
    for (const double scale : {2.0, 4.0})
      for (const double gain : {0.6, 1.0, 1.4}) {
        SCOPED_TRACE(::testing::Message()
                     << "inside " << static_cast<int>(inside) << ", scale " << scale << ", gain " << gain);
        const DrawnMouth m = draw_mouth(inside, opening, opening + 0.1, scale, gain);
        const LipGap gap = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
        ASSERT_TRUE(gap.valid);
        EXPECT_NEAR(gap.darkness, expected.darkness, 0.04);
        EXPECT_NEAR(seal_probability(gap, opening + 0.1), expected_seal, 0.1);
        if (sealed) {
          EXPECT_GT(seal_probability(gap, opening + 0.1), 0.9);
        }
      }
  }
  for (const Inside inside : {Inside::kSealed, Inside::kGreyTeeth, Inside::kShadedSeal}) {
    const double opening = inside == Inside::kGreyTeeth ? 0.15 : 0.0;
    const DrawnMouth reference = draw_mouth(inside, opening, opening + 0.1);
    const LipGap expected = measure_lip_gap(reference.gray, reference.cr, reference.landmarks);
    for (const double scale : {2.0, 4.0}) {
      SCOPED_TRACE(::testing::Message() << "in colour, inside " << static_cast<int>(inside) << ", scale " << scale);
      const DrawnMouth m = draw_mouth(inside, opening, opening + 0.1, scale);
      const LipGap gap = measure_lip_gap(m.gray, m.cr, m.landmarks);
      ASSERT_TRUE(gap.colour);
      EXPECT_NEAR(gap.pallor, expected.pallor, 0.02);
      EXPECT_NEAR(seal_probability(gap, opening + 0.1), seal_probability(expected, opening + 0.1), 0.1);
    }
  }
}

TEST(LipContact, LandmarksWiderThanALaggingClosureAreNeverSealed) {
  const DrawnMouth m = draw_mouth(Inside::kSealed, 0, 0.2);
  const LipGap gap = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
  EXPECT_GT(seal_probability(gap, 0.2), 0.9);
  EXPECT_LT(seal_probability(gap, 0.45), 0.01);  // the landmarks see a wide open mouth
}

TEST(LipContact, NoPixelEvidenceLeavesTheLandmarkHeight) {
  DrawnMouth m = draw_mouth(Inside::kSealed, 0, 0.15);
  m.landmarks.row(1).array() += m.gray.rows;  // the mouth below the image
  const LipGap gap = measure_lip_gap(m.gray, cv::Mat(), m.landmarks);
  EXPECT_FALSE(gap.valid);
  EXPECT_EQ(seal_probability(gap, 0.15), 0);
  EXPECT_DOUBLE_EQ(fused_opening(0.15, 0), 0.15);
  const cv::Mat black = cv::Mat::zeros(m.gray.size(), CV_8UC1);
  EXPECT_FALSE(measure_lip_gap(black, cv::Mat(), draw_mouth(Inside::kSealed, 0, 0.15).landmarks).valid);
}

TEST(LipContact, MeasuringAllocatesNothing) {
  const DrawnMouth m = draw_mouth(Inside::kTeeth, 0.2, 0.25, 2.0);
  const cv::Mat no_colour;
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  double sum = 0;
  for (int i = 0; i < 10; ++i) {
    const LipGap gap = measure_lip_gap(m.gray, i % 2 == 0 ? m.cr : no_colour, m.landmarks);
    sum += fused_opening(0.25, seal_probability(gap, 0.25));
  }
  const long allocations = test::allocation_count() - before;
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocations, 0);
  EXPECT_TRUE(std::isfinite(sum));
}

TEST(TransferToBilabial, SealedArticulationMovesToBMP) {
  constexpr int kBMP = 2, kAah = 0, kOh = 11;
  VisemeWeights w{};
  w[kAah] = 0.4f;
  w[kOh] = 0.2f;
  w[kBMP] = 0.05f;
  VisemeWeights open = w;
  transfer_to_bilabial(open, 0.0);
  EXPECT_EQ(open, w);  // lips apart: nothing moves

  VisemeWeights sealed = w;
  transfer_to_bilabial(sealed, 1.0);
  EXPECT_FLOAT_EQ(sealed[kBMP], 0.4f);
  EXPECT_FLOAT_EQ(sealed[kAah], 0.0f);
  EXPECT_FLOAT_EQ(sealed[kOh], 0.0f);

  VisemeWeights half = w;
  transfer_to_bilabial(half, 0.5);
  EXPECT_FLOAT_EQ(half[kBMP], 0.2f);
  EXPECT_FLOAT_EQ(half[kAah], 0.2f);

  VisemeWeights rest{};  // a sealed mouth at rest stays at rest
  transfer_to_bilabial(rest, 1.0);
  EXPECT_EQ(rest, VisemeWeights{});
}

}  // namespace
}  // namespace lipdrive
