#include "firmware_app/daemon/frame_processor.hpp"

#include "core/lip_contact.hpp"
#include "drivers/clock.hpp"

#include <spdlog/spdlog.h>

#include <cmath>

namespace lipdrive {

FrameProcessor::FrameProcessor(const MorphableModel& model, LandmarkSet set, FitSettings settings,
                               std::shared_ptr<const ShapePredictorData> predictor, const Eigen::VectorXf& identity,
                               const FitOutput::Expressions& rest, AutoIdentity automatic, TrackerSettings tracking)
    : set_(set),
      settings_(settings),
      first_automatic_(identity.size() == 0 && model.has_expressions() && automatic.model ? std::move(automatic)
                                                                                          : AutoIdentity{}),
      first_rest_(rest),
      automatic_(first_automatic_),
      identity_(identity),
      fitter_(model, set, settings, identity),
      arkit_(model.expression_names),
      reference_(mouth_reference(model, identity, std::span<const double>(rest.data(), rest.size()))),
      visemes_(make_viseme_solver(model, set)),
      tracker_(std::move(predictor), tracking),
      rest_(rest) {
  identity_frames_.reserve(static_cast<std::size_t>(automatic_.frames));
}

void FrameProcessor::forget(FaceTracker::Next next) {
  tracker_.reset(next);
  identity_frames_.clear();
  if (next != FaceTracker::Next::kStill || first_automatic_.frames == 0 || identity_.size() == 0) return;
  const MorphableModel& model = *first_automatic_.model;
  automatic_ = first_automatic_;
  identity_ = Eigen::VectorXf();
  rest_ = first_rest_;
  fit_on_identity(model);
}

void FrameProcessor::fit_on_identity(const MorphableModel& model) {
  fitter_ = Fitter(model, set_, settings_, identity_);
  reference_ = mouth_reference(model, identity_, std::span<const double>(rest_.data(), rest_.size()));
  fit_afresh_ = true;
}

// Calibration's two steps (cmd_calibrate.cpp) on the gathered frames: the identity behind them
// (fit_identity), then its rest point (fit_rest_expression). Every later frame is fitted on
// them, warm-started afresh (this frame's fit() stays the one it was fitted with). Until all
// are gathered, the two of the first frame alone carry the fit: on the mean face the difference
// between the faces goes into the expression weights, and from there into the fitted mouth's
// measures (height_fit, width_fit, protrusion_3d); the ARKit weights read 0 until the last.
void FrameProcessor::gather_identity_frame(const Landmarks2D& landmarks) {
  identity_frames_.push_back(landmarks);
  const bool all = static_cast<int>(identity_frames_.size()) >= automatic_.frames;
  if (identity_frames_.size() > 1 && !all) return;
  const std::int64_t start = monotonic_ns();
  const MorphableModel& model = *automatic_.model;
  identity_ = fit_identity(model, set_, identity_frames_);
  rest_ = fit_rest_expression(model, set_, identity_frames_, identity_, settings_);
  fit_on_identity(model);
  if (!all) return;
  spdlog::info(
      "identity: fitted from the first {} tracked frames in {:.1f} ms (no calibrated identity; "
      "`lipdrive calibrate` fits the performer's own)",
      identity_frames_.size(), ms_since(start));
  automatic_ = AutoIdentity{};
  identity_frames_ = {};
}

const FrameMeasurement& FrameProcessor::process(const cv::Mat& gray, const cv::Mat& cr) {
  FrameMeasurement& r = result_;
  r.tracked = false;
  r.fit_ms = r.measures_ms = std::nan("");
  std::int64_t start = monotonic_ns();
  const TrackStatus status = tracker_.track(gray, r.landmarks);
  r.landmarks_ms = ms_since(start);
  r.appearance = tracker_.appearance();
  // With something before the mouth the face is still tracked, but there is no mouth to measure.
  if (status == TrackStatus::kNoFace || tracker_.mouth_hidden()) return r;
  // A newly acquired face may be another pose entirely, and a new identity another shape: do not
  // warm-start from the old one.
  if (status == TrackStatus::kAcquired || fit_afresh_) fit_ = Fitter::initial_output();
  fit_afresh_ = false;
  start = monotonic_ns();
  fitter_.fit(r.landmarks, fit_);
  r.fit_ms = ms_since(start);
  if (!tracker_.check_fit(r.landmarks, fit_.reprojection_error_px)) return r;
  start = monotonic_ns();
  const LipGap lips = measure_lip_gap(gray, cr, r.landmarks);
  if (lips.valid && !tracker_.check_mouth(lips.lip_luma)) return r;
  r.measures = measure_mouth(r.landmarks, fit_, reference_);
  r.measures.seal = seal_probability(lips, r.measures.height_2d);
  r.measures.open = fused_opening(r.measures.height_2d, r.measures.seal);
  // Visemes by the model's kind: from the ARKit weights of the expression fit, or by matching
  // the model's viseme poses; either moves sealed lips to B-M-P.
  if (arkit_.from_fit()) {
    // Until an AutoIdentity is fitted the weights are the mean face's, not this face's: held at 0.
    if (identity_pending())
      above_rest_.setZero();
    else
      above_rest(fit_.expressions, rest_, above_rest_);
    ArkitWeights arkit;
    arkit_.from_expressions(std::span<const double>(above_rest_.data(), above_rest_.size()), arkit);
    r.visemes = visemes_from_arkit(arkit, r.measures.seal);
  } else if (visemes_) {
    r.visemes = visemes_->solve(fit_, r.landmarks);
    transfer_to_bilabial(r.visemes, r.measures.seal);
  }
  r.measures_ms = ms_since(start);
  if (identity_pending()) gather_identity_frame(r.landmarks);  // for the frames after this one
  r.tracked = true;
  return r;
}

}  // namespace lipdrive
