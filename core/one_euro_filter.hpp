// The 1€ filter (Casiez, Roussel & Vogel, "1€ Filter: A Simple Speed-based Low-pass Filter
// for Noisy Input in Interactive Systems", CHI 2012): an exponential low-pass whose cutoff
// rises with the signal's speed, so a still signal is smoothed hard (little jitter) and a
// moving one is followed closely (little lag). Timestamps come from the frames, so dropped
// or late frames change the smoothing exactly as much as the time that passed.
#pragma once

namespace lipdrive {

struct OneEuroSettings {
  double min_cutoff_hz = 1.0;  // f_cmin: cutoff at rest; lower = less jitter, more lag
  double beta = 0.0;           // speed coefficient: cutoff = f_cmin + beta·|dx̂/dt|; higher = less lag
  double d_cutoff_hz = 1.0;    // f_cd: cutoff of the derivative's own low-pass
};

/// One channel's filter state. Fixed size, allocates nothing.
class OneEuroFilter {
 public:
  /// Throws std::invalid_argument unless min_cutoff_hz > 0, beta >= 0, d_cutoff_hz > 0.
  explicit OneEuroFilter(OneEuroSettings settings = {});

  /// Filters sample x taken at time_s (seconds). The first sample after construction or
  /// reset() passes through. A sample not later than the previous one (dt <= 0) cannot be
  /// weighed against elapsed time: it returns the previous output unchanged.
  double filter(double x, double time_s);

  /// Forgets the history (on tracking loss): the next sample passes through.
  void reset() { initialised_ = false; }

 private:
  OneEuroSettings settings_;
  bool initialised_ = false;
  double x_hat_ = 0, dx_hat_ = 0, last_time_s_ = 0;
};

/// Smoothing factor of an exponential low-pass of cutoff fc sampled after dt (1€ paper eq. 3
/// with τ = 1 / (2π fc)): α = 1 / (1 + τ / dt).
double low_pass_alpha(double cutoff_hz, double dt_s);

}  // namespace lipdrive
