#include "firmware_app/outputs/osc_output.hpp"

#include "core/arkit_from_signals.hpp"
#include "core/osc_addresses.hpp"
#include "drivers/clock.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>

namespace lipdrive {

OscOutput::OscOutput(const OscOutputOptions& options, std::span<const ChannelSpec> channels)
    : SenderOutput(fmt::format("osc udp {}:{}", options.host, options.port), options.rate_hz,
                   std::chrono::milliseconds(options.max_backoff_ms)),
      channel_indices_(pick_channels(options.channels, channels, "osc")),
      sender_(options.host, options.port) {
  for (const int index : channel_indices_)
    channel_addresses_.push_back(osc::channel_address(channels[static_cast<std::size_t>(index)].name));
  for (const std::string_view name : kDerivedArkitNames) arkit_addresses_.push_back(fmt::format("/{}", name));
  start();
}

bool OscOutput::send(const DriveFrame& frame) {
  // Before the first result there is no capture time: the tag is the drive frame's own time.
  const std::int64_t moment = frame.capture_time_ns > 0 ? frame.capture_time_ns : frame.time_ns;
  sender_.begin_bundle(osc_time_tag(wall_time_ns(moment)));
  sender_.add(osc::kFrame.data(), static_cast<std::int32_t>(frame.counter));
  sender_.add(osc::kStatus.data(), static_cast<std::int32_t>(frame.status));
  if (frame.timecode >= 0)
    sender_.add(osc::kTimecode.data(), format_frame(frame.timecode, frame.timecode_rate).view().data());
  for (std::size_t i = 0; i < channel_indices_.size(); ++i)
    sender_.add(channel_addresses_[i].c_str(),
                static_cast<float>(frame.values[static_cast<std::size_t>(channel_indices_[i])]));
  const bool found = (frame.status & kStatusTracking) != 0;
  sender_.add(osc::kFound.data(), std::int32_t{found});
  const osc::FaceOscGestures gestures = osc::face_osc_gestures(frame.signals);
  sender_.add(osc::kMouthWidth.data(), gestures.mouth_width);
  sender_.add(osc::kMouthHeight.data(), gestures.mouth_height);
  sender_.add(osc::kJaw.data(), gestures.jaw);
  const DerivedArkitWeights arkit = arkit_from_signals(frame.signals);
  for (std::size_t i = 0; i < arkit.size(); ++i) sender_.add(arkit_addresses_[i].c_str(), arkit[i]);
  if (sender_.send_bundle()) return true;
  failure_ = fmt::format("cannot send a {} byte bundle: {}", sender_.last_size(), std::strerror(errno));
  return false;
}

}  // namespace lipdrive
