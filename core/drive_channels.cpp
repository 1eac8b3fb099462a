#include "core/drive_channels.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lipdrive {

std::optional<int> find_channel(std::span<const ChannelSpec> channels, std::string_view name) {
  const auto found = std::ranges::find(channels, name, &ChannelSpec::name);
  if (found == channels.end()) return std::nullopt;
  return static_cast<int>(found - channels.begin());
}

double map_to_output(const ChannelSpec& spec, double signal_value) {
  double t = std::clamp((signal_value - spec.in_min) / (spec.in_max - spec.in_min), 0.0, 1.0);
  if (spec.invert) t = 1 - t;
  return spec.out_min + t * (spec.out_max - spec.out_min);
}

ChannelBank::ChannelBank(std::span<const ChannelSpec> specs, SafetySettings safety) : safety_(safety) {
  if (specs.size() > kMaxChannels) throw std::invalid_argument("at most " + std::to_string(kMaxChannels) + " channels");
  for (const ChannelSpec& spec : specs) {
    if (!(spec.in_max != spec.in_min))
      throw std::invalid_argument("channel " + spec.name + ": in_min and in_max must differ");
    const double lo = std::min(spec.out_min, spec.out_max), hi = std::max(spec.out_min, spec.out_max);
    if (spec.neutral < lo || spec.neutral > hi)
      throw std::invalid_argument("channel " + spec.name + ": neutral must lie between out_min and out_max");
    if (spec.max_slew_per_s < 0) throw std::invalid_argument("channel " + spec.name + ": max_slew_per_s < 0");
    specs_[static_cast<std::size_t>(count_)] = spec;
    if (spec.smoothed) filters_[static_cast<std::size_t>(count_)] = OneEuroFilter(spec.smoothing);
    neutral_[static_cast<std::size_t>(count_)] = spec.neutral;
    ++count_;
  }
  override_.fill(kNoOverride);
  reset_to_neutral();
}

void ChannelBank::reset_to_neutral() {
  values_ = neutral_;
  held_target_ = neutral_;
  gain_ = 0;
  fail_safe_ = true;
}

ChannelBankState ChannelBank::state() const {
  ChannelBankState state;
  for (std::size_t i = 0; i < static_cast<std::size_t>(count_); ++i)
    state.channels.push_back({specs_[i].name, values_[i], held_target_[i]});
  state.gain = gain_;
  state.last_tracked_ns = last_tracked_ns_;
  return state;
}

void ChannelBank::carry_on(const ChannelBankState& state) {
  for (const ChannelBankState::Channel& carried : state.channels) {
    const std::optional<int> index =
        find_channel(std::span(specs_.data(), static_cast<std::size_t>(count_)), carried.name);
    if (!index) continue;
    const auto i = static_cast<std::size_t>(*index);
    const double lo = std::min(specs_[i].out_min, specs_[i].out_max),
                 hi = std::max(specs_[i].out_min, specs_[i].out_max);
    values_[i] = std::clamp(carried.value, lo, hi);
    held_target_[i] = std::clamp(carried.target, lo, hi);
  }
  gain_ = std::clamp(state.gain, 0.0, 1.0);
  last_tracked_ns_ = state.last_tracked_ns;
}

std::span<const double> ChannelBank::step(const DriveSignals& signals, const DriveInput& input) {
  const double dt_s = stepped_ ? std::max<std::int64_t>(input.now_ns - last_step_ns_, 0) * 1e-9 : 0.0;
  last_step_ns_ = input.now_ns;
  stepped_ = true;

  const bool live = (input.tracked || input.voice) && input.enabled;
  if (live) last_tracked_ns_ = input.now_ns;
  // Within the hold time a loss keeps the last tracked targets at full gain.
  const bool holding =
      input.enabled && !live && last_tracked_ns_ && input.now_ns - *last_tracked_ns_ <= safety_.hold_ns;
  fail_safe_ = !live && !holding;
  const double gain_step = safety_.ease_ns > 0 ? dt_s * 1e9 / static_cast<double>(safety_.ease_ns) : 1.0;
  gain_ = fail_safe_ ? std::max(0.0, gain_ - gain_step) : std::min(1.0, gain_ + gain_step);

  for (std::size_t i = 0; i < static_cast<std::size_t>(count_); ++i) {
    const ChannelSpec& spec = specs_[i];
    double desired;
    if (spec.signal == Signal::kTracking) {
      desired = map_to_output(spec, input.tracked ? 1.0 : 0.0);
    } else {
      // A signal that is not a number (a measure the frame could not make) keeps the last target:
      // NaN passes every clamp, and no servo may be sent it.
      if (live && std::isfinite(signals[spec.signal])) {
        double value = signals[spec.signal];
        if (spec.smoothed) value = filters_[i].filter(value, static_cast<double>(input.frame_time_ns) * 1e-9);
        held_target_[i] = map_to_output(spec, value);
      } else if (!live) {
        filters_[i].reset();
      }
      desired = neutral_[i] + gain_ * (held_target_[i] - neutral_[i]);
    }
    if (!std::isnan(override_[i]))
      desired = std::clamp(override_[i], std::min(spec.out_min, spec.out_max), std::max(spec.out_min, spec.out_max));
    if (spec.max_slew_per_s > 0) {
      const double max_step = spec.max_slew_per_s * dt_s;
      desired = std::clamp(desired, values_[i] - max_step, values_[i] + max_step);
    }
    values_[i] = desired;
  }
  return values();
}

}  // namespace lipdrive
