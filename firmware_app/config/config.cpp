#include "firmware_app/config/config.hpp"

#include "core/audio_rates.hpp"
#include "core/osc_addresses.hpp"
#include "drivers/serial_port.hpp"
#include "drivers/udp_socket.hpp"
#include "firmware_app/config/paths.hpp"
#include "firmware_app/config/performer_profile.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <span>
#include <string_view>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

std::string_view describe_type(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a number";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    default: return "a date or time";
  }
}

/// One table of the file: typed, range-checked reads that remember which keys were read,
/// so that whatever is left over afterwards is an unknown key.
class Section {
 public:
  Section(std::string file, const toml::table* table, std::string name)
      : file_(std::move(file)), table_(table), name_(std::move(name)) {}

  [[noreturn]] void fail(std::string_view key, std::string_view reason) const {
    throw ConfigError(fmt::format("{}: {}", where(key), reason));
  }

  /// "FILE: key KEY".
  std::string where(std::string_view key) const { return fmt::format("{}: key {}", file_, key_path(key)); }

  std::string string(std::string_view key, std::string fallback) {
    const toml::node* node = find(key);
    if (!node) return fallback;
    if (const auto value = node->value_exact<std::string>()) return *value;
    fail(key, fmt::format("must be a string, got {}", describe_type(*node)));
  }

  bool boolean(std::string_view key, bool fallback) {
    const toml::node* node = find(key);
    if (!node) return fallback;
    if (const auto value = node->value_exact<bool>()) return *value;
    fail(key, fmt::format("must be true or false, got {}", describe_type(*node)));
  }

  double number(std::string_view key, double fallback, double min, double max) {
    const toml::node* node = find(key);
    if (!node) return fallback;
    const auto value = node->value<double>();  // integers are numbers too
    if (!value || !(node->is_floating_point() || node->is_integer()))
      fail(key, fmt::format("must be a number, got {}", describe_type(*node)));
    if (!(*value >= min && *value <= max))
      fail(key, fmt::format("must be between {} and {}, got {}", min, max, *value));
    return *value;
  }

  std::vector<std::string> strings(std::string_view key) {
    const toml::node* node = find(key);
    std::vector<std::string> values;
    if (!node) return values;
    const toml::array* array = node->as_array();
    if (!array) fail(key, fmt::format("must be an array of strings, got {}", describe_type(*node)));
    for (const toml::node& element : *array) {
      const auto value = element.value_exact<std::string>();
      if (!value) fail(key, fmt::format("must be an array of strings, has {}", describe_type(element)));
      values.push_back(*value);
    }
    return values;
  }

  int integer(std::string_view key, int fallback, int min, int max) {
    const toml::node* node = find(key);
    if (!node) return fallback;
    const auto value = node->value_exact<std::int64_t>();
    if (!value) fail(key, fmt::format("must be an integer, got {}", describe_type(*node)));
    if (*value < min || *value > max) fail(key, fmt::format("must be between {} and {}, got {}", min, max, *value));
    return static_cast<int>(*value);
  }

  std::string one_of(std::string_view key, std::string fallback, std::initializer_list<std::string_view> choices) {
    return one_of(key, std::move(fallback), std::span(choices.begin(), choices.size()));
  }
  std::string one_of(std::string_view key, std::string fallback, std::span<const std::string_view> choices) {
    std::string value = string(key, std::move(fallback));
    if (std::ranges::find(choices, value) == choices.end())
      fail(key, fmt::format("must be one of {}, got \"{}\"", fmt::join(choices, ", "), value));
    return value;
  }

  /// A sub-table; absent means all defaults.
  Section table(std::string_view key) {
    const toml::node* node = find(key);
    if (node && !node->is_table()) fail(key, fmt::format("must be a table, got {}", describe_type(*node)));
    return Section(file_, node ? node->as_table() : nullptr, key_path(key));
  }

  /// An array of tables ([[key]]), each named "key[i]" in messages; absent means none.
  std::vector<Section> tables(std::string_view key) {
    const toml::node* node = find(key);
    std::vector<Section> sections;
    if (!node) return sections;
    const toml::array* array = node->as_array();
    if (!array || !array->is_array_of_tables())
      fail(key, fmt::format("must be an array of tables ([[{}]]), got {}", key_path(key), describe_type(*node)));
    for (std::size_t i = 0; i < array->size(); ++i)
      sections.emplace_back(file_, array->get(i)->as_table(), fmt::format("{}[{}]", key_path(key), i));
    return sections;
  }

  /// The keys of a sub-table (for tables keyed by name, like `servos = { jaw = 0 }`).
  std::vector<std::string> keys_of(std::string_view key) const {
    std::vector<std::string> keys;
    const toml::node* node = table_ ? table_->get(key) : nullptr;
    if (node && node->is_table())
      for (const auto& [name, value] : *node->as_table()) keys.emplace_back(name.str());
    return keys;
  }

  void reject_unknown_keys() const {
    if (!table_) return;
    for (const auto& [key, node] : *table_) {
      if (std::ranges::find(read_, key.str()) == read_.end()) fail(key.str(), "unknown key");
    }
  }

 private:
  std::string key_path(std::string_view key) const {
    return name_.empty() ? std::string(key) : fmt::format("{}.{}", name_, key);
  }
  const toml::node* find(std::string_view key) {
    read_.emplace_back(key);
    return table_ ? table_->get(key) : nullptr;
  }

  std::string file_;
  const toml::table* table_;
  std::string name_;
  std::vector<std::string> read_;
};

/// What a path in the file must name: a device node is not a model, and a FIFO given as a clip
/// would block the daemon's start until something writes to it.
enum class PathIs { kFile, kFileOrFolder, kDevice };

/// What `status` is, for a message: "a folder", "a FIFO", ...
std::string_view type_name(const fs::file_status& status) {
  switch (status.type()) {
    case fs::file_type::regular: return "a file";
    case fs::file_type::directory: return "a folder";
    case fs::file_type::character: return "a character device";
    case fs::file_type::block: return "a block device";
    case fs::file_type::fifo: return "a FIFO";
    case fs::file_type::socket: return "a socket";
    default: return "neither a file nor a folder";
  }
}

/// `path` when it exists and is what `is` asks (symbolic links followed); `kind` names what it
/// should be in the message.
fs::path existing(Section& section, std::string_view key, const fs::path& path, std::string_view kind,
                  PathIs is = PathIs::kFile) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) section.fail(key, fmt::format("no such {}: {}", kind, path.string()));
  const bool fits = is == PathIs::kDevice
                        ? fs::is_character_file(status)
                        : fs::is_regular_file(status) || (is == PathIs::kFileOrFolder && fs::is_directory(status));
  if (!fits) section.fail(key, fmt::format("{} is {}, not a {}", path.string(), type_name(status), kind));
  return path;
}

void read_log(Section log, Config& config) {
  const std::string level = log.one_of("level", "info", {"trace", "debug", "info", "warn", "error"});
  config.log_level = spdlog::level::from_str(level);
  log.reject_unknown_keys();
}

void read_model(Section model, Config& config) {
  const std::string file = model.string("file", "");
  if (!file.empty()) config.model.file = file;
  existing(model, "file", config.model.file, "model file");
  const std::string set =
      model.one_of("landmark_set", std::string(landmark_set_name(config.model.landmark_set)), kLandmarkSetNames);
  config.model.landmark_set = *parse_landmark_set(set);
  config.model.iterations = model.integer("iterations", config.model.iterations, 1, 20);
  config.model.auto_identity_frames =
      model.integer("auto_identity_frames", config.model.auto_identity_frames, 0, CalibrationCapture::kCapacity);
  model.reject_unknown_keys();
}

void read_tracker(Section tracker, Config& config) {
  const std::string file = tracker.string("predictor", "");
  if (!file.empty()) config.tracker.predictor = file;
  existing(tracker, "predictor", config.tracker.predictor, "predictor file");
  config.tracker.settings.min_face_px =
      tracker.number("min_face_px", config.tracker.settings.min_face_px, kDetectorWindowPx, 4096);
  tracker.reject_unknown_keys();
}

void read_faults(Section faults, SimulatedCameraOptions::FaultInjection& out) {
  constexpr int kMaxFrames = 1'000'000, kMaxMs = 60'000;
  out.drop_every = faults.integer("drop_every", 0, 0, kMaxFrames);
  out.stall_every = faults.integer("stall_every", 0, 0, kMaxFrames);
  out.stall = std::chrono::milliseconds(faults.integer("stall_ms", 0, 0, kMaxMs));
  out.disconnect_after = faults.integer("disconnect_after", 0, 0, kMaxFrames);
  out.reconnect = std::chrono::milliseconds(faults.integer("reconnect_ms", 0, 0, kMaxMs));
  out.corrupt_every = faults.integer("corrupt_every", 0, 0, kMaxFrames);
  faults.reject_unknown_keys();
}

void read_controls(Section controls, V4l2Controls& out) {
  out.exposure_us = controls.integer("exposure_us", 0, 0, 1'000'000);
  out.gain = controls.integer("gain", -1, -1, 65'535);
  out.power_line_hz = controls.integer("power_line_hz", -1, -1, 60);
  if (out.power_line_hz != -1 && out.power_line_hz != 0 && out.power_line_hz != 50 && out.power_line_hz != 60)
    controls.fail("power_line_hz", fmt::format("must be -1, 0, 50 or 60, got {}", out.power_line_hz));
  out.keep_frame_rate = controls.boolean("keep_frame_rate", true);
  controls.reject_unknown_keys();
}

/// What of a camera must be there when the file is read.
struct CameraNeeds {
  bool recording = false;  // the clip or folder a simulated camera replays
  bool device = false;     // a V4L2 camera's device node; a libcamera camera, when it is opened
};

void read_camera(Section camera, Config::Camera& config_camera, CameraNeeds needs) {
  const std::string type = camera.one_of("type", "sim", {"sim", "v4l2", "libcamera"});
  config_camera.type = type == "sim"    ? Config::Camera::Type::kSim
                       : type == "v4l2" ? Config::Camera::Type::kV4l2
                                        : Config::Camera::Type::kLibcamera;
#ifndef LIPDRIVE_HAVE_LIBCAMERA
  if (config_camera.type == Config::Camera::Type::kLibcamera)
    camera.fail("type", "this build has no libcamera support (configure with -DLIPDRIVE_WITH_LIBCAMERA=ON)");
#endif

  // Both cameras' keys are allowed whatever the type, so switching type is a one-line edit.
  SimulatedCameraOptions& sim = config_camera.sim;
  const std::string input = camera.string("input", "");
  sim.input = input.empty() ? default_fixture_path() : fs::path(input);
  sim.real_time = camera.boolean("real_time", true);
  sim.loop = camera.boolean("loop", true);
  sim.replay_rate = camera.integer("replay_fps", 0, 0, 240);
  read_faults(camera.table("faults"), sim.faults);

  V4l2Options& v4l2 = config_camera.v4l2;
  v4l2.device = camera.string("device", "/dev/video0");
  const std::string format = camera.string("format", "auto");
  try {
    v4l2.format = parse_pixel_format(format);
  } catch (const std::invalid_argument& e) {
    camera.fail("format", e.what());
  }
  v4l2.width = static_cast<unsigned>(camera.integer("width", 640, 0, 8192));
  v4l2.height = static_cast<unsigned>(camera.integer("height", 480, 0, 8192));
  v4l2.frame_rate = camera.integer("fps", 60, 1, 240);
  read_controls(camera.table("controls"), v4l2.controls);
  config_camera.libcamera_id = camera.string("camera_id", "");
  config_camera.wait_when_absent = !needs.device;
  const int rotation = camera.integer("rotation", 0, 0, 270);
  if (const auto turn = rotation_from_degrees(rotation))
    config_camera.rotation = *turn;
  else
    camera.fail("rotation", fmt::format("{} is not a quarter turn: 0, 90, 180 or 270 (degrees clockwise)", rotation));
  camera.reject_unknown_keys();

  if (needs.recording && config_camera.type == Config::Camera::Type::kSim)
    existing(camera, "input", sim.input, "file or folder", PathIs::kFileOrFolder);
  if (needs.device && config_camera.type == Config::Camera::Type::kV4l2)
    existing(camera, "device", v4l2_device_path(v4l2.device), "device", PathIs::kDevice);
}

/// [side_camera]: the keys of [camera], plus whether it is used and where the face looks.
void read_side_camera(Section side, Config& config, CameraNeeds needs) {
  const bool enabled = side.boolean("enabled", false);
  const std::string facing = side.one_of("facing", "right", {"right", "left"});
  config.side_facing = facing == "right" ? ProfileFacing::kRight : ProfileFacing::kLeft;
  Config::Camera camera;
  read_camera(side, camera, enabled ? needs : CameraNeeds{});
  config.side_rotation = camera.rotation;
  if (enabled) config.side_camera = camera;
}

void read_recording(Section recording, Config& config) {
  Config::Recording& r = config.recording;
  r.dir = recording.string("dir", r.dir.string());
  // An empty path is the working directory, which a service does not choose.
  if (r.dir.empty()) recording.fail("dir", "must name the folder takes are written to");
  // Made when the first take starts, if it is not there yet.
  std::error_code ec;
  if (const fs::file_status status = fs::status(r.dir, ec); fs::exists(status) && !fs::is_directory(status))
    recording.fail("dir", fmt::format("{} is {}, not a folder", r.dir.string(), type_name(status)));
  r.start = recording.boolean("start", r.start);
  r.flush_interval_ms = recording.integer("flush_interval_ms", r.flush_interval_ms, 10, 60'000);
  recording.reject_unknown_keys();
}

void read_status(Section status, Config& config) {
  config.status.print_interval_ms = status.integer("print_interval_ms", config.status.print_interval_ms, 0, 3'600'000);
  status.reject_unknown_keys();
}

void read_scheduling(Section scheduling, Config& config) {
  Config::Scheduling& s = config.scheduling;
  s.realtime_priority = scheduling.integer("realtime_priority", s.realtime_priority, 0, 99);
  s.cpu_latency_us = scheduling.integer("cpu_latency_us", s.cpu_latency_us, -1, 10'000);
  s.warm_ahead_us = scheduling.integer("warm_ahead_us", s.warm_ahead_us, 0, 100'000);
  scheduling.reject_unknown_keys();
}

void read_performer(Section performer, Config& config, bool check_profile) {
  Config::Performer& p = config.performer;
  p.name = performer.string("name", "");
  p.profiles_dir = performer.string("profiles_dir", p.profiles_dir.string());
  p.neutral_frames =
      performer.integer("neutral_frames", p.neutral_frames, kMinNeutralFrames, CalibrationCapture::kCapacity);
  performer.reject_unknown_keys();
  if (p.name.empty()) return;
  try {
    const fs::path profile = profile_path(p.profiles_dir, p.name);
    if (check_profile) existing(performer, "name", profile, "performer profile (run `lipdrive calibrate`)");
  } catch (const std::invalid_argument& e) {
    performer.fail("name", e.what());
  }
}

void read_safety(Section safety, Config& config) {
  constexpr std::int64_t kNsPerMs = 1'000'000;
  SafetySettings& s = config.safety;
  s.hold_ns = safety.integer("hold_ms", static_cast<int>(s.hold_ns / kNsPerMs), 0, 60'000) * kNsPerMs;
  s.ease_ns = safety.integer("ease_ms", static_cast<int>(s.ease_ns / kNsPerMs), 0, 60'000) * kNsPerMs;
  safety.reject_unknown_keys();
}

void read_channels(std::vector<Section> channels, Config& config) {
  if (channels.size() > kMaxChannels) {
    Section(config.file.string(), nullptr, "").fail("channels", fmt::format("at most {} channels", kMaxChannels));
  }
  constexpr double kMaxOut = 65535, kMaxIn = 1e6;
  for (Section& channel : channels) {
    ChannelSpec spec;
    spec.name = channel.string("name", "");
    if (spec.name.empty()) channel.fail("name", "every channel needs a name");
    if (find_channel(config.channels, spec.name))
      channel.fail("name", fmt::format("\"{}\" is already a channel", spec.name));
    const std::string signal = channel.string("signal", "open");
    if (const auto parsed = parse_signal(signal)) {
      spec.signal = *parsed;
    } else {
      channel.fail(
          "signal",
          fmt::format("unknown signal \"{}\" (open, width, protrusion, tracking, seal, viseme_<name>, arkit_<name>)",
                      signal));
    }
    spec.in_min = channel.number("in_min", 0, -kMaxIn, kMaxIn);
    spec.in_max = channel.number("in_max", 1, -kMaxIn, kMaxIn);
    if (spec.in_min == spec.in_max) channel.fail("in_max", "must differ from in_min");
    spec.out_min = channel.number("out_min", 0, -kMaxOut, kMaxOut);
    spec.out_max = channel.number("out_max", 1000, -kMaxOut, kMaxOut);
    spec.neutral = channel.number("neutral", spec.out_min, -kMaxOut, kMaxOut);
    if (spec.neutral < std::min(spec.out_min, spec.out_max) || spec.neutral > std::max(spec.out_min, spec.out_max))
      channel.fail("neutral", fmt::format("must lie between out_min {} and out_max {}", spec.out_min, spec.out_max));
    spec.max_slew_per_s = channel.number("max_slew_per_s", 0, 0, 1e9);
    spec.invert = channel.boolean("invert", false);
    Section smoothing = channel.table("smoothing");
    spec.smoothed = channel.keys_of("smoothing").size() > 0;
    spec.smoothing.min_cutoff_hz = smoothing.number("min_cutoff_hz", 1.0, 0.01, 1000);
    spec.smoothing.beta = smoothing.number("beta", 0.0, 0, 1e6);
    spec.smoothing.d_cutoff_hz = smoothing.number("d_cutoff_hz", 1.0, 0.01, 1000);
    smoothing.reject_unknown_keys();
    channel.reject_unknown_keys();
    config.channels.push_back(std::move(spec));
  }
}

/// Channel names an output refers to must exist.
void check_channel_names(Section& output, std::string_view key, const std::vector<std::string>& names,
                         const Config& config) {
  for (const std::string& name : names) {
    if (!find_channel(config.channels, name))
      output.fail(key, fmt::format("no channel named \"{}\" (see [[channels]])", name));
  }
}

SerialPortSettings read_serial_line(Section& section, std::string_view default_device) {
  SerialPortSettings line;
  line.device = section.string("device", std::string(default_device));
  line.baud = section.integer("baud", line.baud, 50, 4'000'000);
  line.parity = section.one_of("parity", std::string(1, line.parity), {"N", "E", "O"})[0];
  line.data_bits = section.integer("data_bits", line.data_bits, 5, 8);
  line.stop_bits = section.integer("stop_bits", line.stop_bits, 1, 2);
  line.rs485 = section.boolean("rs485", line.rs485);
  try {
    validate_serial_settings(line);
  } catch (const std::invalid_argument& e) {
    // The ranges above leave the device and the baud to be refused here.
    section.fail(line.device.empty() ? "device" : "baud", e.what());
  }
  return line;
}

/// The host must resolve now: a typo shows at check-config, not as silence on the show network.
UdpEndpoint resolved(Section& section, std::string_view key, const std::string& host, int port) {
  try {
    return resolve_udp(host, port);
  } catch (const UdpError& e) {
    fail_unresolved(section.where(key), e);
  }
}

/// libmodbus's TCP contexts take a numeric IPv4 address alone: a name (inet_addr() makes it
/// INADDR_NONE) had the server listen on 255.255.255.255 and the client fail with "Network is
/// unreachable" for ever. A name is resolved now, once, as the OSC host is.
std::string numeric_ipv4(Section& section, std::string_view key, const std::string& host, int port) {
  const UdpEndpoint found = resolved(section, key, host, port);
  if (found.address.ss_family != AF_INET)
    section.fail(key, fmt::format("host \"{}\" has no IPv4 address (Modbus TCP takes IPv4 only)", host));
  char numeric[INET_ADDRSTRLEN] = {};
  ::inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(&found.address)->sin_addr, numeric, sizeof numeric);
  return numeric;
}

ModbusEndpoint read_modbus_link(Section& section) {
  ModbusEndpoint link;
  link.transport = section.one_of("transport", "tcp", {"tcp", "rtu"}) == "tcp" ? ModbusEndpoint::Transport::kTcp
                                                                               : ModbusEndpoint::Transport::kRtu;
  link.address = section.string("address", link.address);
  link.port = section.integer("port", link.port, 1, 65535);
  if (link.transport == ModbusEndpoint::Transport::kTcp)
    link.address = numeric_ipv4(section, "address", link.address, link.port);
  link.line = read_serial_line(section, kDefaultRtuDevice);
  link.unit_id = section.integer("unit_id", link.unit_id, 1, 247);
  return link;
}

/// [[outputs.dmx]]: the channels' slots follow each other from start_address unless a
/// channel gives its own address; no slot may be used twice in one universe, across outputs
/// too.
void read_dmx_outputs(std::vector<Section> outputs, Config& config) {
  for (Section& dmx : outputs) {
    DmxOutputOptions options;
    options.universe = static_cast<unsigned>(dmx.integer("universe", 1, 1, 63999));
    int next = dmx.integer("start_address", 1, 1, kDmxUniverseSlots);
    options.rate_hz = dmx.integer("rate_hz", options.rate_hz, 1, 44);
    options.priority = dmx.integer("priority", options.priority, 0, 200);
    options.rpc_port = dmx.integer("rpc_port", options.rpc_port, 1, 65535);
    options.max_backoff_ms = dmx.integer("max_backoff_ms", options.max_backoff_ms, 10, 600'000);
    std::vector<Section> channels = dmx.tables("channels");
    if (channels.empty()) dmx.fail("channels", "needs at least one [[outputs.dmx.channels]] entry");
    for (Section& channel : channels) {
      DmxSlotSpec spec;
      spec.channel = channel.string("name", "");
      const auto index = find_channel(config.channels, spec.channel);
      if (!index) channel.fail("name", fmt::format("no channel named \"{}\" (see [[channels]])", spec.channel));
      const ChannelSpec& drive = config.channels[static_cast<std::size_t>(*index)];
      spec.channel_index = *index;
      spec.range_min = drive.out_min;
      spec.range_max = drive.out_max;
      if (spec.range_min == spec.range_max)
        channel.fail("name", fmt::format("channel \"{}\" has out_min = out_max: nothing to send", spec.channel));
      const int bits = channel.integer("bits", 8, 8, 16);
      if (bits != 8 && bits != 16) channel.fail("bits", fmt::format("must be 8 or 16, got {}", bits));
      spec.sixteen_bit = bits == 16;
      spec.address = channel.integer("address", next, 1, kDmxUniverseSlots);
      next = spec.last_address() + 1;
      channel.reject_unknown_keys();
      options.footprint.push_back(spec);
    }
    // This output's slots after those of the outputs before it on the same universe.
    std::vector<DmxSlotSpec> universe;
    for (const DmxOutputOptions& before : config.outputs.dmx)
      if (before.universe == options.universe)
        universe.insert(universe.end(), before.footprint.begin(), before.footprint.end());
    const std::size_t earlier = universe.size();
    universe.insert(universe.end(), options.footprint.begin(), options.footprint.end());
    if (const auto error = check_footprint(universe)) {
      // The earlier outputs passed alone: the entry at fault is one of this output's.
      channels[error->index - earlier].fail("address", error->reason);
    }
    dmx.reject_unknown_keys();
    config.outputs.dmx.push_back(std::move(options));
  }
}

void read_osc_outputs(std::vector<Section> outputs, Config& config) {
  for (Section& osc : outputs) {
    OscOutputOptions options;
    options.host = osc.string("host", options.host);
    options.port = osc.integer("port", options.port, 1, 65535);
    resolved(osc, "host", options.host, options.port);
    options.channels = osc.strings("channels");
    check_channel_names(osc, "channels", options.channels, config);
    std::vector<std::string> names = options.channels;
    if (names.empty())
      for (const ChannelSpec& channel : config.channels) names.push_back(channel.name);
    for (const std::string& name : names) {
      if (!osc::is_address_part(name))
        osc.fail("channels", fmt::format("channel \"{}\" cannot be part of an OSC address (no spaces or # * , / ? [ ] "
                                         "{{ }})",
                                         name));
      if (name == "frame" || name == "status" || name == "timecode")
        osc.fail("channels", fmt::format("channel \"{}\" would hide /lipdrive/{}; rename the channel", name, name));
    }
    options.rate_hz = osc.integer("rate_hz", options.rate_hz, 1, 1000);
    options.max_backoff_ms = osc.integer("max_backoff_ms", options.max_backoff_ms, 10, 600'000);
    osc.reject_unknown_keys();
    config.outputs.osc.push_back(std::move(options));
  }
}

/// The keys of an ALSA capture input (device, channels, channel) at `sample_rate`; blocks of
/// 10 ms. The device is opened when the daemon starts, not here: a USB microphone may be
/// plugged in later (`lipdrive check-config` tries it).
void read_alsa_input(Section& section, int sample_rate, AlsaCaptureOptions& alsa) {
  alsa.device = section.string("device", alsa.device);
  if (alsa.device.empty()) section.fail("device", "must name an ALSA capture device (e.g. \"default\", \"hw:1,0\")");
  alsa.channels = section.integer("channels", alsa.channels, 1, 8);
  alsa.channel = section.integer("channel", alsa.channel, 0, 7);
  if (alsa.channel >= alsa.channels)
    section.fail("channel", fmt::format("must be below channels ({}), got {}", alsa.channels, alsa.channel));
  alsa.sample_rate = sample_rate;
  alsa.period_frames = std::min(sample_rate / 100, kMaxAudioBlockFrames);
}

void read_timecode(Section timecode, Config& config) {
  Config::Timecode& t = config.timecode;
  const std::string source = timecode.one_of("source", "none", {"none", "clock", "ltc"});
  t.source = source == "none"    ? Config::Timecode::Source::kNone
             : source == "clock" ? Config::Timecode::Source::kClock
                                 : Config::Timecode::Source::kLtc;
  const double fps = timecode.number("fps", 25, 1, 120);
  if (const auto rate = rate_from_fps(fps))
    t.rate = *rate;
  else
    timecode.fail("fps", fmt::format("must be 24, 25, 29.97 (drop-frame) or 30, got {}", fps));
  // Where LTC comes from: a sound card input or the generated signal.
  t.input = timecode.one_of("ltc_input", "sim", {"sim", "alsa"}) == "alsa" ? Config::Timecode::Input::kAlsa
                                                                           : Config::Timecode::Input::kSim;
  const std::string start = timecode.string("sim_start", "10:00:00:00");
  const auto label = parse_timecode(start);
  if (!label || !frame_from_timecode(*label, t.rate))
    timecode.fail("sim_start",
                  fmt::format("\"{}\" is not a timecode at {} fps (HH:MM:SS:FF)", start, rate_name(t.rate)));
  t.sim.start = *label;
  t.sim.rate = t.rate;
  const std::string signal = timecode.one_of("sim_signal", "ltc", {"ltc", "silence", "noise"});
  t.sim.signal = signal == "ltc"       ? SimulatedLtcSignal::kLtc
                 : signal == "silence" ? SimulatedLtcSignal::kSilence
                                       : SimulatedLtcSignal::kNoise;
  const double sim_fps = timecode.number("sim_fps", fps, 1, 120);
  if (const auto rate = rate_from_fps(sim_fps))
    t.sim.rate = *rate;
  else
    timecode.fail("sim_fps", fmt::format("must be 24, 25, 29.97 (drop-frame) or 30, got {}", sim_fps));
  t.sim.sample_rate = timecode.integer("sample_rate", t.sim.sample_rate, kMinAudioSampleRate, kMaxAudioSampleRate);
  read_alsa_input(timecode, t.sim.sample_rate, t.alsa);
  timecode.reject_unknown_keys();
}

void read_voice(Section voice, Config& config) {
  Config::Voice& v = config.voice;
  v.enabled = voice.boolean("enabled", v.enabled);
  v.model = voice.string("model", "");
  v.input = voice.one_of("input", "sim", {"sim", "alsa"}) == "alsa" ? Config::Voice::Input::kAlsa
                                                                    : Config::Voice::Input::kSim;
  const int sample_rate = voice.integer("sample_rate", v.alsa.sample_rate, kMinAudioSampleRate, kMaxVoiceSampleRate);
  read_alsa_input(voice, sample_rate, v.alsa);
  v.crossfade_ms = voice.integer("crossfade_ms", v.crossfade_ms, 0, 2000);
  v.audio_timeout_ms = voice.integer("audio_timeout_ms", v.audio_timeout_ms, 20, 5000);
  voice.reject_unknown_keys();
  if (!v.enabled) return;
  if (v.model.empty()) voice.fail("model", "must name the performer's voice model (.lpv, `lipdrive voice train`)");
  existing(voice, "model", v.model, "voice model file");
  if (v.input == Config::Voice::Input::kSim) {
    if (config.camera.type != Config::Camera::Type::kSim)
      voice.fail("input", "\"sim\" plays the simulated camera's clip: [camera] type must be \"sim\"");
    if (config.camera.sim.replay_rate > 0 || !config.camera.sim.real_time)
      voice.fail("input",
                 "\"sim\" plays the clip's sound at its own rate: [camera] needs real_time = true and no replay_fps");
  }
}

void read_osc_control(Section control, Config& config) {
  Config::OscControl& c = config.osc_control;
  c.enabled = control.boolean("enabled", c.enabled);
  c.address = control.string("address", c.address);
  c.port = control.integer("port", c.port, 1, 65535);
  if (c.enabled) resolved(control, "address", c.address, c.port);
  control.reject_unknown_keys();
}

void read_monitor(Section monitor, Config& config) {
  Config::Monitor& m = config.monitor;
  m.enabled = monitor.boolean("enabled", m.enabled);
  // Not resolved here: an address that cannot be listened on leaves the daemon running without
  // the page (Monitor::start logs why).
  m.address = monitor.string("address", m.address);
  m.port = monitor.integer("port", m.port, 1, 65535);
  m.token = monitor.string("token", m.token);
  if (!m.token.empty() && (m.token.size() < 16 || !std::ranges::all_of(m.token, [](char c) {
                             return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
                           })))
    monitor.fail("token", "must be at least 16 letters, digits, '-', '_' or '.' (or \"\" for a new one at start)");
  m.preview_fps = monitor.integer("preview_fps", m.preview_fps, 1, 30);
  m.preview_size = monitor.integer("preview_size", m.preview_size, 64, 4096);
  m.max_clients = monitor.integer("max_clients", m.max_clients, 1, 64);
  monitor.reject_unknown_keys();
}

void read_outputs(Section outputs, Config& config) {
  for (Section& server : outputs.tables("modbus_server")) {
    ModbusServerOptions options;
    options.link = read_modbus_link(server);
    options.max_clients = server.integer("max_clients", options.max_clients, 1, 64);
    server.reject_unknown_keys();
    config.outputs.modbus_servers.push_back(options);
  }
  for (Section& client : outputs.tables("modbus_client")) {
    ModbusClientOptions options;
    options.link = read_modbus_link(client);
    options.channels = client.strings("channels");
    check_channel_names(client, "channels", options.channels, config);
    options.first_register = client.integer("first_register", options.first_register, 0, 65535);
    // One register per channel, all of them in one write request.
    const std::size_t registers = options.channels.empty() ? config.channels.size() : options.channels.size();
    if (options.first_register + registers > 65536)
      client.fail("first_register", fmt::format("{} channels from register {} run past the last register, 65535",
                                                registers, options.first_register));
    options.rate_hz = client.integer("rate_hz", options.rate_hz, 1, 1000);
    options.timeout_ms = client.integer("timeout_ms", options.timeout_ms, 1, 2000);
    options.max_backoff_ms = client.integer("max_backoff_ms", options.max_backoff_ms, 10, 600'000);
    client.reject_unknown_keys();
    config.outputs.modbus_clients.push_back(options);
  }
  for (Section& serial : outputs.tables("serial")) {
    SerialOutputOptions options;
    const std::string mode = serial.one_of("mode", "framed", {"framed", "line", "maestro"});
    options.mode = mode == "framed" ? SerialOutputOptions::Mode::kFramed
                   : mode == "line" ? SerialOutputOptions::Mode::kLine
                                    : SerialOutputOptions::Mode::kMaestro;
    options.line = read_serial_line(serial, kDefaultSerialDevice);
    options.channels = serial.strings("channels");
    check_channel_names(serial, "channels", options.channels, config);
    Section servos = serial.table("servos");
    for (const std::string& channel : serial.keys_of("servos")) {
      options.servos.push_back({channel, servos.integer(channel, 0, 0, 23)});
      check_channel_names(servos, channel, {channel}, config);
    }
    if (options.mode == SerialOutputOptions::Mode::kMaestro && options.servos.empty())
      serial.fail("servos", "maestro mode needs servos = { <channel> = <servo number>, ... }");
    options.max_backoff_ms = serial.integer("max_backoff_ms", options.max_backoff_ms, 10, 600'000);
    serial.reject_unknown_keys();
    config.outputs.serial.push_back(options);
  }
  read_dmx_outputs(outputs.tables("dmx"), config);
  read_osc_outputs(outputs.tables("osc"), config);
  Section gpio = outputs.table("gpio");
  GpioOptions& g = config.outputs.gpio;
  g.enabled = gpio.boolean("enabled", g.enabled);
  g.chip = gpio.string("chip", g.chip);
  g.status_line = gpio.string("status_line", "");
  g.fault_line = gpio.string("fault_line", "");
  g.calibrate_button = gpio.string("calibrate_button", "");
  g.record_button = gpio.string("record_button", "");
  g.enable_switch = gpio.string("enable_switch", "");
  g.buttons_active_low = gpio.boolean("buttons_active_low", g.buttons_active_low);
  const std::string bias = gpio.one_of("input_bias", "auto", kGpioBiasNames);
  g.input_bias = static_cast<GpioBias>(std::ranges::find(kGpioBiasNames, bias) - kGpioBiasNames.begin());
  g.debounce_ms = gpio.integer("debounce_ms", g.debounce_ms, 0, 1000);
  gpio.reject_unknown_keys();
  outputs.reject_unknown_keys();
}

}  // namespace

void fail_unresolved(const std::string& where, const UdpError& error) {
  if (error.temporary())
    throw CommandError(fmt::format("{}: {}; trying again is all it needs once the network is up", where, error.what()),
                       kExitTryAgain);
  throw ConfigError(fmt::format("{}: {}", where, error.what()));
}

Config load_config(const fs::path& file, ConfigUse use) {
  const std::string name = file.string();
  // toml++ reads a directory as an empty file: every default, silently; and says a file it
  // cannot open "could not be opened", not why.
  std::error_code ec;
  if (const fs::file_status status = fs::status(file, ec); fs::exists(status) && !fs::is_regular_file(status))
    throw ConfigError(fmt::format("{}: cannot read the file: not a regular file", name));
  if (std::FILE* readable = std::fopen(name.c_str(), "r"))
    std::fclose(readable);
  else
    throw ConfigError(fmt::format("{}: cannot read the file: {}", name, std::strerror(errno)));
  toml::table root;
  try {
    root = toml::parse_file(name);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    if (where.line == 0) throw ConfigError(fmt::format("{}: cannot read the file: {}", name, e.description()));
    throw ConfigError(fmt::format("{}:{}:{}: {}", name, where.line, where.column, e.description()));
  }
  // A file cut to nothing (an editor's save on a full disk, a copy that failed) would run the
  // daemon on every default: no output, the figure not driven. A reload keeps the running one.
  if (root.empty()) throw ConfigError(fmt::format("{}: the file holds no settings (empty, or cut short?)", name));
  Config config;
  config.file = file;
  Section top(name, &root, "");
  read_log(top.table("log"), config);
  read_model(top.table("model"), config);
  read_tracker(top.table("tracker"), config);
  // Recordings stand in for the cameras: a file written for the rig loads anywhere. The daemon
  // waits for a camera that is not there yet (a USB camera enumerated after it started at
  // boot, a CSI camera whose ISP is: drivers/v4l2_camera.hpp, drivers/libcamera_camera.hpp);
  // calibrate on the camera needs it now.
  const CameraNeeds needs{.recording = use == ConfigUse::kDaemon || use == ConfigUse::kCalibrateCamera,
                          .device = use == ConfigUse::kCalibrateCamera};
  read_camera(top.table("camera"), config.camera, needs);
  read_side_camera(top.table("side_camera"), config, needs);
  read_recording(top.table("recording"), config);
  read_status(top.table("status"), config);
  read_scheduling(top.table("scheduling"), config);
  // The profile calibrate writes need not exist yet.
  const bool check_profile = use == ConfigUse::kDaemon || use == ConfigUse::kOffline;
  read_performer(top.table("performer"), config, check_profile);
  read_safety(top.table("safety"), config);
  read_channels(top.tables("channels"), config);
  read_outputs(top.table("outputs"), config);
  read_osc_control(top.table("osc_control"), config);
  read_monitor(top.table("monitor"), config);
  read_timecode(top.table("timecode"), config);
  read_voice(top.table("voice"), config);
  top.reject_unknown_keys();
  return config;
}

}  // namespace lipdrive
