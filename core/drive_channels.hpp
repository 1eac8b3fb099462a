// Drive channels and the safety layer (docs/data-flow.md): each channel follows one signal, maps
// its input range to the output's units, and is clamped, slew-rate limited and eased to
// its neutral value when tracking is lost. Pure computation on fixed-size state: step()
// allocates nothing and does a fixed amount of work per channel.
#pragma once

#include "core/drive_signals.hpp"
#include "core/one_euro_filter.hpp"

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

inline constexpr int kMaxChannels = 32;

struct ChannelSpec {
  std::string name;  // how outputs and the register map refer to it
  Signal signal = Signal::kOpen;
  double in_min = 0, in_max = 1;  // signal range mapped onto [out_min, out_max], clamped
  double out_min = 0, out_max = 1000;
  double neutral = 0;         // the safe pose, in output units
  double max_slew_per_s = 0;  // output units per second; 0 = unlimited
  bool invert = false;        // in_min maps to out_max
  bool smoothed = false;      // 1€-filter the signal (frame timestamps) before mapping
  OneEuroSettings smoothing{};
};

/// The index of the channel named `name` among `channels`, or nullopt: the one lookup by name
/// (the configuration's checks, the outputs that pick channels by name).
std::optional<int> find_channel(std::span<const ChannelSpec> channels, std::string_view name);

struct SafetySettings {
  std::int64_t hold_ns = 250'000'000;  // keep the last tracked values this long after a loss
  std::int64_t ease_ns = 500'000'000;  // then ease to neutral over this long (and back on return)
};

/// Target in output units for one signal value: linear map, clamped to the output range.
double map_to_output(const ChannelSpec& spec, double signal_value);

/// What step() needs besides the signals.
struct DriveInput {
  bool tracked = false;            // the signals come from a tracked face
  bool voice = false;              // the signals come from the voice (the face is lost): they drive like a face's
  bool enabled = true;             // outputs enabled; disabled eases to neutral like a loss
  std::int64_t now_ns = 0;         // monotonic
  std::int64_t frame_time_ns = 0;  // capture time of the signals: the smoothing's clock
};

/// Where a drive stands when its pipeline is stopped for a reload, by channel name: what the
/// drive of the reloaded configuration carries on from (ChannelBank::carry_on), so that a
/// reload moves no channel.
struct ChannelBankState {
  struct Channel {
    std::string name;
    double value = 0;   // the last value sent, output units
    double target = 0;  // the target the fail-safe gain scales towards (held while tracking is lost)
  };
  std::vector<Channel> channels;
  double gain = 0;                              // the fail-safe gain
  std::optional<std::int64_t> last_tracked_ns;  // monotonic; none: never tracked
};

/// The state of all channels of one drive. Channel values start at neutral (or, after
/// carry_on(), where a reload found them).
///
/// The fail-safe is one gain g in [0, 1] shared by all channels: value = neutral +
/// g (target - neutral). While tracked (or the voice drives), g rises to 1 over ease_ns; when tracking has been lost
/// for hold_ns it falls to 0 over ease_ns, the targets frozen at the last tracked values, so
/// neither the loss nor the return makes a jump. The slew limit applies last, to everything
/// including overrides. Channels following kTracking report the state and are not eased.
/// Smoothed channels filter the signal on the frames' capture times, so idle ticks (the same
/// frame again) leave it unchanged; a loss resets the filter, so a new track starts fresh.
class ChannelBank {
 public:
  static constexpr double kNoOverride = std::numeric_limits<double>::quiet_NaN();

  /// Throws std::invalid_argument for more than kMaxChannels channels, an empty input range
  /// or a neutral value outside the output range.
  ChannelBank(std::span<const ChannelSpec> specs, SafetySettings safety);

  /// Advances every channel to `input.now_ns` and returns the values in output units.
  std::span<const double> step(const DriveSignals& signals, const DriveInput& input);

  /// A manual value (output units) for channel `index`, or kNoOverride; slew-limited and clamped.
  void set_override(int index, double value) { override_[static_cast<std::size_t>(index)] = value; }

  std::span<const double> values() const { return {values_.data(), static_cast<std::size_t>(count_)}; }
  /// The neutral values, as the last thing the drive sends when the daemon stops.
  void reset_to_neutral();
  /// Where the drive stands, for the drive that replaces it (allocates: not on the frame path).
  ChannelBankState state() const;
  /// Before the first step(): every channel named in `state` carries on from its value and
  /// target (clamped to this channel's output range), and the fail-safe from its gain and its
  /// last tracked time, so the slew limit, the hold and the ease go on from there. A channel
  /// `state` does not name starts at its neutral.
  void carry_on(const ChannelBankState& state);
  /// Tracking is lost (past hold_ns) or outputs are disabled: values are easing to neutral.
  bool fail_safe_active() const { return fail_safe_; }
  int size() const { return count_; }

 private:
  std::array<ChannelSpec, kMaxChannels> specs_;
  std::array<OneEuroFilter, kMaxChannels> filters_;
  std::array<double, kMaxChannels> values_{}, neutral_{}, held_target_{}, override_{};
  int count_ = 0;
  SafetySettings safety_;
  double gain_ = 0;  // 0 at start: the drive eases in from neutral when tracking first arrives
  bool fail_safe_ = true;
  std::optional<std::int64_t> last_tracked_ns_;  // none until the face is first tracked: nothing to hold
  std::int64_t last_step_ns_ = 0;
  bool stepped_ = false;
};

}  // namespace lipdrive
