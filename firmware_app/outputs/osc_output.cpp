#include "firmware_app/outputs/osc_output.hpp"

#include "core/arkit.hpp"
#include "core/osc_addresses.hpp"
#include "drivers/clock.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstring>

namespace lipdrive {
namespace {

/// The messages of a bundle, in their order (docs/osc.md).
std::vector<OscBundle::Message> bundle_layout(std::span<const int> channel_indices,
                                              std::span<const ChannelSpec> channels, bool with_timecode) {
  using Type = OscBundle::Type;
  std::vector<OscBundle::Message> m{{std::string(osc::kFrame), Type::kInt32},
                                    {std::string(osc::kStatus), Type::kInt32}};
  if (with_timecode) m.push_back({std::string(osc::kTimecode), Type::kString, TimecodeText{}.view().size()});
  for (const int index : channel_indices)
    m.push_back({osc::channel_address(channels[static_cast<std::size_t>(index)].name), Type::kFloat});
  m.push_back({std::string(osc::kFound), Type::kInt32});
  for (const std::string_view gesture : {osc::kMouthWidth, osc::kMouthHeight, osc::kJaw})
    m.push_back({std::string(gesture), Type::kFloat});
  for (const std::string_view name : kArkitNames) m.push_back({osc::arkit_address(name), Type::kFloat});
  return m;
}

}  // namespace

OscOutput::OscOutput(const OscOutputOptions& options, std::span<const ChannelSpec> channels)
    : SenderOutput(fmt::format("osc udp {}:{}", options.host, options.port), options.rate_hz,
                   std::chrono::milliseconds(options.max_backoff_ms)),
      channel_indices_(pick_channels(options.channels, channels, "osc")),
      with_timecode_(bundle_layout(channel_indices_, channels, true)),
      without_timecode_(bundle_layout(channel_indices_, channels, false)),
      sender_(options.host, options.port) {
  start();
}

void OscOutput::fill(OscBundle& bundle, const DriveFrame& frame, bool with_timecode) const {
  // Before the first result there is no capture time: the tag is the drive frame's own time.
  const std::int64_t moment = frame.capture_time_ns > 0 ? frame.capture_time_ns : frame.time_ns;
  bundle.set_time_tag(osc_time_tag(wall_time_ns(moment)));
  std::size_t i = 0;
  bundle.set(i++, static_cast<std::int32_t>(frame.counter));
  bundle.set(i++, static_cast<std::int32_t>(frame.status));
  if (with_timecode) bundle.set(i++, format_frame(frame.timecode, frame.timecode_rate).view());
  for (const int index : channel_indices_)
    bundle.set(i++, static_cast<float>(frame.values[static_cast<std::size_t>(index)]));
  bundle.set(i++, std::int32_t{(frame.status & kStatusTracking) != 0});
  // The signals describe the face as measured: one the frame could not measure (NaN) goes out
  // as 0, never as a NaN a receiver would pass on.
  const auto finite = [](float value) { return std::isfinite(value) ? value : 0.0f; };
  const osc::FaceOscGestures gestures = osc::face_osc_gestures(frame.signals);
  for (const float gesture : {gestures.mouth_width, gestures.mouth_height, gestures.jaw})
    bundle.set(i++, finite(gesture));
  for (const float weight : frame.signals.arkit()) bundle.set(i++, finite(weight));
}

bool OscOutput::send(const DriveFrame& frame) {
  const bool with_timecode = frame.timecode >= 0;
  OscBundle& bundle = with_timecode ? with_timecode_ : without_timecode_;
  fill(bundle, frame, with_timecode);
  if (sender_.send(bundle)) return true;
  failure_ = fmt::format("cannot send a {} byte bundle: {}", bundle.bytes().size(), std::strerror(errno));
  return false;
}

}  // namespace lipdrive
