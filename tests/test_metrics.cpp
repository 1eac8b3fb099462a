// compare_series (docs/method.md 5) on series whose metrics can be worked out by hand.
#include "core/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace lipdrive {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kTolerance = 1e-12;

TEST(CompareSeries, PerfectMatchHasNoErrorAndFullCorrelation) {
  const std::vector<double> z = {1, 3, 2, 5, 4};
  const SeriesAgreement a = compare_series(z, z);
  EXPECT_EQ(a.pairs_used, 5);
  EXPECT_NEAR(a.rmse_scaled, 0, kTolerance);
  EXPECT_NEAR(a.mae, 0, kTolerance);
  EXPECT_NEAR(a.max_abs_error, 0, kTolerance);
  EXPECT_NEAR(a.pearson_r, 1, kTolerance);
  EXPECT_NEAR(a.std_ratio, 1, kTolerance);
}

TEST(CompareSeries, AffineOutputHasZeroScaledErrorButRawErrorAndDoubleSpread) {
  const std::vector<double> z = {0, 1, 2, 3};
  const std::vector<double> z_hat = {3, 5, 7, 9};  // 2z + 3: errors 3, 4, 5, 6
  const SeriesAgreement a = compare_series(z, z_hat);
  EXPECT_NEAR(a.rmse_scaled, 0, kTolerance);
  EXPECT_NEAR(a.mae, 4.5, kTolerance);
  EXPECT_NEAR(a.max_abs_error, 6, kTolerance);
  EXPECT_NEAR(a.pearson_r, 1, kTolerance);
  EXPECT_NEAR(a.std_ratio, 2, kTolerance);
}

TEST(CompareSeries, ReversedSeriesIsAntiCorrelated) {
  const std::vector<double> z = {0, 1, 2};
  const std::vector<double> z_hat = {2, 1, 0};
  const SeriesAgreement a = compare_series(z, z_hat);
  EXPECT_NEAR(a.pearson_r, -1, kTolerance);
  EXPECT_NEAR(a.std_ratio, 1, kTolerance);
  // Scaled: (0, .5, 1) vs (1, .5, 0): squared errors 1, 0, 1 → sqrt(2/3).
  EXPECT_NEAR(a.rmse_scaled, std::sqrt(2.0 / 3.0), kTolerance);
  EXPECT_NEAR(a.mae, 4.0 / 3.0, kTolerance);
  EXPECT_NEAR(a.max_abs_error, 2, kTolerance);
}

TEST(CompareSeries, HandComputedScaledRmseAndCorrelation) {
  const std::vector<double> z = {0, 2, 4};      // scaled 0, .5, 1
  const std::vector<double> z_hat = {0, 4, 4};  // scaled 0, 1, 1
  const SeriesAgreement a = compare_series(z, z_hat);
  EXPECT_NEAR(a.rmse_scaled, std::sqrt(0.25 / 3.0), kTolerance);
  EXPECT_NEAR(a.mae, 2.0 / 3.0, kTolerance);
  EXPECT_NEAR(a.max_abs_error, 2, kTolerance);
  // Centred: z (-2, 0, 2), ẑ (-8/3, 4/3, 4/3): cov sum 8, sums of squares 8 and 32/3.
  EXPECT_NEAR(a.pearson_r, 8 / std::sqrt(8 * 32.0 / 3.0), kTolerance);
  EXPECT_NEAR(a.std_ratio, std::sqrt((32.0 / 3.0) / 8), kTolerance);
}

TEST(CompareSeries, SkipsPairsWhereEitherValueIsNaN) {
  const std::vector<double> z = {0, kNaN, 1, 2, 3};
  const std::vector<double> z_hat = {0, 7, 1, kNaN, 5};
  const SeriesAgreement a = compare_series(z, z_hat);
  EXPECT_EQ(a.pairs_used, 3);  // frames 0, 2 and 4
  EXPECT_NEAR(a.mae, 2.0 / 3.0, kTolerance);
  EXPECT_NEAR(a.max_abs_error, 2, kTolerance);
  // (0,1,3) vs (0,1,5): scaled (0,1/3,1) vs (0,.2,1).
  EXPECT_NEAR(a.rmse_scaled, std::sqrt(std::pow(1.0 / 3.0 - 0.2, 2) / 3.0), kTolerance);
}

TEST(CompareSeries, ConstantSeriesScaleToZero) {
  const std::vector<double> z = {2, 2, 2, 2};
  const SeriesAgreement same = compare_series(z, std::vector<double>{5, 5, 5, 5});
  EXPECT_NEAR(same.rmse_scaled, 0, kTolerance);  // both flat: same shape
  EXPECT_NEAR(same.mae, 3, kTolerance);
  EXPECT_TRUE(std::isnan(same.pearson_r));
  EXPECT_TRUE(std::isnan(same.std_ratio));

  // Flat truth (zeros after scaling) vs a full swing 0, 1/3, 2/3, 1.
  const SeriesAgreement moving = compare_series(z, std::vector<double>{0, 1, 2, 3});
  EXPECT_NEAR(moving.rmse_scaled, std::sqrt((0 + 1.0 / 9 + 4.0 / 9 + 1) / 4), kTolerance);
  EXPECT_TRUE(std::isnan(moving.pearson_r));
  EXPECT_TRUE(std::isnan(moving.std_ratio));

  // Flat output against moving truth: correlation undefined, no spread at all.
  const SeriesAgreement frozen = compare_series(std::vector<double>{0, 1, 2, 3}, z);
  EXPECT_TRUE(std::isnan(frozen.pearson_r));
  EXPECT_NEAR(frozen.std_ratio, 0, kTolerance);
}

TEST(CompareSeries, NoUsablePairsGivesNaN) {
  const SeriesAgreement a = compare_series(std::vector<double>{kNaN, 1}, std::vector<double>{2, kNaN});
  EXPECT_EQ(a.pairs_used, 0);
  EXPECT_TRUE(std::isnan(a.rmse_scaled));
  EXPECT_TRUE(std::isnan(a.mae));
  EXPECT_TRUE(std::isnan(a.pearson_r));
}

TEST(CompareSeries, RejectsSeriesOfDifferentLength) {
  EXPECT_THROW(compare_series(std::vector<double>{1, 2}, std::vector<double>{1}), std::invalid_argument);
}

// A transcript of 19 frames: sil, bin, at, blue, now, sil.
const std::vector<WordFrames> kWords = {{0, 2, "sil", true},   {3, 5, "bin", false},  {6, 6, "at", false},
                                        {7, 8, "blue", false}, {9, 10, "now", false}, {11, 18, "sil", true}};

TEST(ClosureMetric, WorkedExample) {
  // Range 0..10, so the scaled value is v / 10.
  const std::vector<double> v = {5, 5, 5, 10, 1, 10, 10, 10, 10, 10, 10, 0, 2, 0, 0, 1, 0, 0, 0};
  const ClosureMetric m = closure_metric(v, kWords, 25);
  ASSERT_EQ(m.bilabial_words, 2);
  EXPECT_EQ(m.closures_seen, 1);
  ASSERT_EQ(m.words.size(), 2u);
  EXPECT_EQ(m.words[0].word, "bin");
  EXPECT_NEAR(m.words[0].minimum, 0.1, kTolerance);  // frames 1..7 widened: frame 4
  EXPECT_TRUE(m.words[0].closed);
  EXPECT_EQ(m.words[1].word, "blue");
  EXPECT_NEAR(m.words[1].minimum, 1.0, kTolerance);  // frames 5..10 never close
  EXPECT_FALSE(m.words[1].closed);
  // Speech frames 3..10: seven at 1.0 and one at 0.1; the 90th percentile by nearest rank is
  // the 8th of 8.
  EXPECT_NEAR(m.opening, 1.0, kTolerance);
  // Final silence from frame 14 (11 + 3) to 18: 0, 0.1, 0, 0, 0.
  EXPECT_NEAR(m.silence_median, 0.0, kTolerance);
  EXPECT_NEAR(m.silence_jitter, (0.1 + 0.1) / 4, kTolerance);
}

TEST(ClosureMetric, UntrackedFramesAreLeftOutNotCountedAsClosed) {
  std::vector<double> v = {5, 5, 5, 10, 1, 10, 10, 10, 10, 10, 10, 0, 2, 0, 0, 1, 0, 0, 0};
  v[4] = kNaN;  // the closure frame was not tracked
  v[16] = kNaN;
  const ClosureMetric m = closure_metric(v, kWords, 25);
  EXPECT_NEAR(m.words[0].minimum, 0.5, kTolerance);
  EXPECT_FALSE(m.words[0].closed);
  EXPECT_EQ(m.closures_seen, 0);
  // Silence frames 14, 15, 17, 18: steps only between neighbours that were both tracked.
  EXPECT_NEAR(m.silence_jitter, (0.1 + 0.0) / 2, kTolerance);
}

TEST(ClosureMetric, BilabialWordsOfTheGridGrammar) {
  for (const char* word : {"bin", "blue", "by", "place", "please", "b", "p", "m"})
    EXPECT_TRUE(is_bilabial_word(word)) << word;
  for (const char* word : {"bat", "sil", "set", "lay", "f", "n", "white", "soon"})
    EXPECT_FALSE(is_bilabial_word(word)) << word;
  const std::vector<double> flat(19, 3.0);
  const ClosureMetric m = closure_metric(flat, kWords, 25);  // no range: everything scales to 0
  EXPECT_EQ(m.closures_seen, 2);
  EXPECT_NEAR(m.opening, 0.0, kTolerance);
  const ClosureMetric none = closure_metric(flat, std::vector<WordFrames>{{0, 18, "bin", false}}, 25);
  EXPECT_TRUE(std::isnan(none.silence_median));  // no silence in the transcript
}

TEST(ClosureMetric, ATranscriptThatDoesNotEndInSilenceHasNoFinalSilence) {
  // A long opening silence, then words to the end: no silence runs to the end.
  const std::vector<WordFrames> words = {{0, 10, "sil", true}, {11, 14, "bin", false}, {15, 18, "now", false}};
  const std::vector<double> v = {0, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 10, 0, 10, 10, 10, 10, 10, 10};
  const ClosureMetric m = closure_metric(v, words, 25);
  EXPECT_TRUE(std::isnan(m.silence_median)) << m.silence_median;
  EXPECT_TRUE(std::isnan(m.silence_jitter)) << m.silence_jitter;
  EXPECT_EQ(m.closures_seen, 1);
}

}  // namespace
}  // namespace lipdrive
