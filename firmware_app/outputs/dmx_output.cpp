#include "firmware_app/outputs/dmx_output.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <thread>

namespace lipdrive {
namespace {

std::size_t highest_slot(const DmxOutputOptions& options) {
  int last = 1;
  for (const DmxSlotSpec& spec : options.footprint) last = std::max(last, spec.last_address());
  return static_cast<std::size_t>(last);
}

}  // namespace

DmxOutput::DmxOutput(const DmxOutputOptions& options)
    : SenderOutput(fmt::format("dmx universe {} slots 1..{} via olad 127.0.0.1:{}", options.universe,
                               highest_slot(options), options.rpc_port),
                   options.rate_hz, std::chrono::milliseconds(options.max_backoff_ms)),
      options_(options),
      slots_(highest_slot(options)),
      client_(options.rpc_port) {
  start();
}

bool DmxOutput::send(const DriveFrame& frame) {
  if (!client_.connected() && !client_.connect()) return false;
  encode_dmx(options_.footprint, frame.values, universe_);
  return client_.send(options_.universe, {universe_.data(), slots_}, static_cast<std::uint8_t>(options_.priority));
}

void DmxOutput::close() {
  // olad drops a source's data when its connection closes: give it a moment to take the last
  // frame (the neutral pose) off the socket first. Bounded, once, at stop.
  if (client_.connected()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  client_.disconnect();
}

}  // namespace lipdrive
