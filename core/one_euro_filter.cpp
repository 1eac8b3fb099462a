#include "core/one_euro_filter.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace lipdrive {

double low_pass_alpha(double cutoff_hz, double dt_s) {
  const double tau = 1 / (2 * std::numbers::pi * cutoff_hz);
  return 1 / (1 + tau / dt_s);
}

OneEuroFilter::OneEuroFilter(OneEuroSettings settings) : settings_(settings) {
  if (!(settings.min_cutoff_hz > 0) || !(settings.beta >= 0) || !(settings.d_cutoff_hz > 0))
    throw std::invalid_argument("1€ filter: min_cutoff_hz and d_cutoff_hz must be > 0 and beta >= 0");
}

double OneEuroFilter::filter(double x, double time_s) {
  if (!initialised_) {
    initialised_ = true;
    x_hat_ = x;
    dx_hat_ = 0;
    last_time_s_ = time_s;
    return x_hat_;
  }
  const double dt = time_s - last_time_s_;
  if (!(dt > 0)) return x_hat_;
  last_time_s_ = time_s;
  // The derivative of the raw signal against the last estimate, low-passed at d_cutoff
  // (paper: dx̂ is filtered so that noise does not open the main cutoff).
  const double dx = (x - x_hat_) / dt;
  dx_hat_ += low_pass_alpha(settings_.d_cutoff_hz, dt) * (dx - dx_hat_);
  // The speed-adaptive cutoff (paper eq. 4) and the main low-pass.
  const double cutoff = settings_.min_cutoff_hz + settings_.beta * std::abs(dx_hat_);
  x_hat_ += low_pass_alpha(cutoff, dt) * (x - x_hat_);
  return x_hat_;
}

}  // namespace lipdrive
