#include "firmware_app/config.hpp"

#include "firmware_app/paths.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cstdint>
#include <initializer_list>
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
    throw ConfigError(fmt::format("{}: key {}: {}", file_, key_path(key), reason));
  }

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

  int integer(std::string_view key, int fallback, int min, int max) {
    const toml::node* node = find(key);
    if (!node) return fallback;
    const auto value = node->value_exact<std::int64_t>();
    if (!value) fail(key, fmt::format("must be an integer, got {}", describe_type(*node)));
    if (*value < min || *value > max) fail(key, fmt::format("must be between {} and {}, got {}", min, max, *value));
    return static_cast<int>(*value);
  }

  std::string one_of(std::string_view key, std::string fallback, std::initializer_list<std::string_view> choices) {
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

/// `path` when it exists; `kind` names what it should be in the message.
fs::path existing(Section& section, std::string_view key, const fs::path& path, std::string_view kind) {
  std::error_code ec;
  if (!fs::exists(path, ec)) section.fail(key, fmt::format("no such {}: {}", kind, path.string()));
  return path;
}

void read_log(Section log, Config& config) {
  const std::string level = log.one_of("level", "info", {"trace", "debug", "info", "warn", "error"});
  config.log_level = spdlog::level::from_str(level);
  log.reject_unknown_keys();
}

void read_model(Section model, Config& config) {
  const std::string file = model.string("file", "");
  config.model.file = existing(model, "file", file.empty() ? default_model_path() : fs::path(file), "model file");
  const std::string set = model.one_of("landmark_set", "F4", {"F1", "F2", "F3", "F4", "F5"});
  config.model.landmark_set = *parse_landmark_set(set);
  config.model.iterations = model.integer("iterations", 3, 1, 20);
  model.reject_unknown_keys();
}

void read_tracker(Section tracker, Config& config) {
  config.tracker.predictor = existing(
      tracker, "predictor", tracker.string("predictor", "/usr/share/dlib/shape_predictor_68_face_landmarks.dat"),
      "predictor file");
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

void read_camera(Section camera, Config& config) {
  const std::string type = camera.one_of("type", "sim", {"sim", "v4l2"});
  config.camera.type = type == "sim" ? Config::Camera::Type::kSim : Config::Camera::Type::kV4l2;

  // Both cameras' keys are allowed whatever the type, so switching type is a one-line edit.
  SimulatedCameraOptions& sim = config.camera.sim;
  const std::string input = camera.string("input", "");
  sim.input = input.empty() ? default_fixture_path() : fs::path(input);
  sim.real_time = camera.boolean("real_time", true);
  sim.loop = camera.boolean("loop", true);
  read_faults(camera.table("faults"), sim.faults);

  V4l2Options& v4l2 = config.camera.v4l2;
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
  camera.reject_unknown_keys();

  if (config.camera.type == Config::Camera::Type::kSim)
    existing(camera, "input", sim.input, "file or folder");
  else
    existing(camera, "device", v4l2.device, "device");
}

void read_recording(Section recording, Config& config) {
  config.recording.dir = recording.string("dir", "/var/lib/lipdrive/takes");
  config.recording.start = recording.boolean("start", false);
  config.recording.flush_interval_ms = recording.integer("flush_interval_ms", 500, 10, 60'000);
  recording.reject_unknown_keys();
}

void read_status(Section status, Config& config) {
  config.status.print_interval_ms = status.integer("print_interval_ms", 1000, 0, 3'600'000);
  status.reject_unknown_keys();
}

}  // namespace

Config load_config(const fs::path& file) {
  const std::string name = file.string();
  toml::table root;
  try {
    root = toml::parse_file(name);
  } catch (const toml::parse_error& e) {
    const auto& where = e.source().begin;
    if (where.line == 0) throw ConfigError(fmt::format("{}: cannot read the file: {}", name, e.description()));
    throw ConfigError(fmt::format("{}:{}:{}: {}", name, where.line, where.column, e.description()));
  }
  Config config;
  config.file = file;
  Section top(name, &root, "");
  read_log(top.table("log"), config);
  read_model(top.table("model"), config);
  read_tracker(top.table("tracker"), config);
  read_camera(top.table("camera"), config);
  read_recording(top.table("recording"), config);
  read_status(top.table("status"), config);
  top.reject_unknown_keys();
  return config;
}

}  // namespace lipdrive
