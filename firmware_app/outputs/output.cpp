#include "firmware_app/outputs/output.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <stdexcept>

namespace lipdrive {

std::vector<int> pick_channels(std::span<const std::string> names, std::span<const ChannelSpec> channels,
                               std::string_view output) {
  std::vector<int> indices;
  if (names.empty()) {
    for (std::size_t i = 0; i < channels.size(); ++i) indices.push_back(static_cast<int>(i));
    return indices;
  }
  for (const std::string& name : names) {
    const std::optional<int> index = find_channel(channels, name);
    if (!index) {
      std::vector<std::string_view> known;
      for (const ChannelSpec& channel : channels) known.push_back(channel.name);
      throw std::invalid_argument(
          fmt::format("{}: unknown channel '{}' (channels: {})", output, name, fmt::join(known, ", ")));
    }
    indices.push_back(*index);
  }
  return indices;
}

}  // namespace lipdrive
