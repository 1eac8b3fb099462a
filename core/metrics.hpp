// Agreement between a ground-truth series and an output series (docs/method.md 5).
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

/// How well an output series ẑ follows a ground-truth series z over the same frames.
/// Every field is NaN when no pair was usable.
struct SeriesAgreement {
  int pairs_used = 0;        // frames where both z and ẑ are finite
  double rmse_scaled = 0;    // RMSE after min–max scaling each series to [0, 1]
  double mae = 0;            // mean absolute error, raw units
  double max_abs_error = 0;  // largest absolute error, raw units
  double pearson_r = 0;      // NaN when either series is constant
  double std_ratio = 0;      // σ(ẑ)/σ(z); NaN when z is constant
};

/// Compares `output` with `truth` element by element; pairs where either value is
/// NaN (e.g. an untracked frame) are skipped. The min–max scaled RMSE compares shape
/// and timing independently of units and gain; a constant series has no range and
/// scales to all zeros (scikit-learn's MinMaxScaler convention), so two constant
/// series agree perfectly. The standard-deviation ratio exposes under-articulation
/// (ratio < 1) that smoothing can cause. Throws std::invalid_argument when the
/// series differ in length.
SeriesAgreement compare_series(std::span<const double> truth, std::span<const double> output);

/// How a mouth series driven by the voice (ẑ) follows the video's (z) of the same recording,
/// as Deena (2012) scores speech-driven animation: Pearson r and σ(ẑ)/σ(z) over the speech
/// frames only (silence would flatter r); and the rest it comes to in the final silence:
/// |median ẑ - median z| over those frames, divided by the range (max - min) of z over every
/// finite frame, so 0.1 is a tenth of the clip's movement.
struct SpeechAgreement {
  int speech_frames = 0;           // pairs used for r and the ratio
  double pearson_r = 0;            // NaN when either is constant
  double std_ratio = 0;            // NaN when z is constant
  double silence_distance = 0;     // NaN without a final silence
};

/// `speech[f]`: frame f lies inside a spoken word; NaN values are skipped. `final_silence`:
/// the frames [first, last] of the final silence, or first > last for none. Throws
/// std::invalid_argument when the spans differ in length.
SpeechAgreement speech_agreement(std::span<const double> truth, std::span<const double> output,
                                 const std::vector<bool>& speech, int final_silence_first, int final_silence_last);

/// A word of a transcript and the video frames it spans (inclusive).
struct WordFrames {
  int first = 0, last = 0;
  std::string_view word;
  bool silence = false;  // "sil" / "sp"
};

/// The GRID words whose articulation closes the lips: bin, blue, by, place, please and the
/// letters b, p, m ("m" is spoken /em/, so its closure comes at its end).
bool is_bilabial_word(std::string_view word);

/// How one bilabial word fared in closure_metric.
struct WordClosure {
  std::string word;
  int first = 0, last = 0;  // the word's frames, before widening
  double minimum = 0;       // smallest scaled value in the widened window; NaN when no tracked frame
  bool closed = false;      // minimum <= kClosureLevel
  bool outside = false;     // the word's frames all lie outside the series: not scored
};

/// Whether a mouth-opening series closes on the bilabial words and opens on the others.
/// Per clip, the series is min-max scaled over its tracked (finite) frames. A bilabial word
/// shows its closure when the minimum scaled value over its frames widened by kWidening_s on
/// each side is at most kClosureLevel. Opening: the 90th percentile (nearest rank) of the
/// scaled values over the frames of non-silence words. Final silence: from kSilenceDelay_s
/// after the start of the transcript's last word, when it is a silence, to its end, the median
/// of the scaled values and their mean absolute frame-to-frame change (jitter, over
/// consecutive tracked frames).
struct ClosureMetric {
  static constexpr double kClosureLevel = 0.2;
  /// 2 and 3 frames of GRID's 25 fps video, as times, so that a recording at another frame
  /// rate is scored over the same stretches.
  static constexpr double kWidening_s = 0.08, kSilenceDelay_s = 0.12;
  int bilabial_words = 0, closures_seen = 0;
  std::vector<WordClosure> words;  // every bilabial word, in transcript order
  double opening = 0;              // NaN when no speech frame was tracked
  double silence_median = 0;       // NaN when the transcript ends without a silence or it was not tracked
  double silence_jitter = 0;
};

/// `values[f]` is frame f's value at `frames_per_second`, NaN when it was not tracked; words
/// are clipped to the series, and a bilabial word wholly outside it is listed as outside,
/// neither a closure nor one of bilabial_words (the recording does not hold it). The values are
/// min-max scaled by the range of `scale_by` (all of a recording's values, where `values` holds
/// only the frames the words reach), by their own when it is empty.
ClosureMetric closure_metric(std::span<const double> values, std::span<const WordFrames> words,
                             double frames_per_second, std::span<const double> scale_by = {});

}  // namespace lipdrive
