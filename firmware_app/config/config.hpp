// The daemon's configuration file (TOML; config/lipdrive.toml is the documented reference).
//
// Everything is validated when the file is loaded, before anything starts: unknown keys,
// wrong types, out-of-range values and missing files (model, predictor, sim input, v4l2
// device; the last two only where the cameras are used, ConfigUse) all throw ConfigError,
// so a typo never silently falls back to a default.
#pragma once

#include "core/dmx_footprint.hpp"
#include "core/drive_channels.hpp"
#include "core/face_tracker.hpp"
#include "core/fitting.hpp"
#include "core/image_rotation.hpp"
#include "core/landmarks.hpp"
#include "core/side_profile.hpp"
#include "core/timecode.hpp"
#include "drivers/alsa_capture.hpp"
#include "drivers/gpio_lines.hpp"
#include "drivers/modbus_link.hpp"
#include "drivers/ola_client.hpp"
#include "drivers/serial_port.hpp"
#include "drivers/udp_socket.hpp"
#include "drivers/v4l2_camera.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/paths.hpp"
#include "sim/ltc_generator.hpp"
#include "sim/simulated_camera.hpp"

#include <spdlog/common.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lipdrive {

/// "FILE: key KEY: reason"; exits with kExitConfig.
class ConfigError : public CommandError {
 public:
  explicit ConfigError(const std::string& message) : CommandError(message, kExitConfig) {}
};

/// A host named at `where` ("FILE: key KEY") that did not resolve: a ConfigError, or, when no
/// name server answered (UdpError::temporary(): at boot before the network is up), a
/// CommandError with kExitTryAgain, which the systemd unit restarts the daemon on, where it
/// stops for good on a configuration error.
[[noreturn]] void fail_unresolved(const std::string& where, const UdpError& error);

/// The serial device a table names when it names none: Modbus RTU adapters are usually
/// USB-RS-485 (ttyUSB), serial outputs microcontroller boards (USB CDC, ttyACM).
inline constexpr const char* kDefaultRtuDevice = "/dev/ttyUSB0";
inline constexpr const char* kDefaultSerialDevice = "/dev/ttyACM0";

/// [[outputs.modbus_server]]: serves the register map (docs/modbus-register-map.md).
struct ModbusServerOptions {
  ModbusEndpoint link;  // TCP address and port, or RTU over a serial line
  int max_clients = 8;  // tcp: connections served at once
};

/// [[outputs.modbus_client]]: writes channels to holding registers of a remote slave.
struct ModbusClientOptions {
  ModbusEndpoint link;
  std::vector<std::string> channels;  // written in this order from first_register; empty = all
  int first_register = 0;
  int rate_hz = 50;           // writes per second at most
  int timeout_ms = 100;       // per request
  int max_backoff_ms = 5000;  // reconnect delay doubles up to this after failures
};

/// [[outputs.serial]]: channel values over a serial line (docs/serial-protocol.md).
struct SerialOutputOptions {
  enum class Mode { kFramed, kLine, kMaestro };
  Mode mode = Mode::kFramed;
  SerialPortSettings line;            // the line (USB CDC, RS-232/RS-485 adapter, pty)
  std::vector<std::string> channels;  // framed and line: sent in this order; empty = all
  /// maestro: Maestro servo number for each channel (channel values are in microseconds).
  struct Servo {
    std::string channel;
    int servo = 0;  // 0..23
  };
  std::vector<Servo> servos;
  int max_backoff_ms = 5000;  // reopen delay doubles up to this while the port is gone
};

/// [[outputs.dmx]]: channels as slots of a DMX512 universe through olad (docs/dmx.md).
struct DmxOutputOptions {
  unsigned universe = 1;               // olad's universe number, 1..63999 (the sACN range)
  std::vector<DmxSlotSpec> footprint;  // checked: inside the universe, no slot twice
  int rate_hz = 44;                    // frames per second at most, 1..44 (a full DMX512 universe)
  int priority = 100;                  // olad's source priority, 0..200
  int rpc_port = kOlaDefaultRpcPort;   // olad's RPC port on 127.0.0.1
  int max_backoff_ms = 1000;           // reconnect delay doubles up to this while olad is away
};

/// [[outputs.osc]]: every drive frame as one OSC bundle (docs/osc.md).
struct OscOutputOptions {
  std::string host = "127.0.0.1";  // a name or a numeric address; resolved when loaded
  int port = 9000;
  std::vector<std::string> channels;  // sent as /lipdrive/<channel>; empty = all
  int rate_hz = 200;                  // bundles per second at most (the newest frame wins)
  int max_backoff_ms = 1000;          // retry delay doubles up to this while sends fail
};

/// [outputs.gpio]: status and fault lines, calibrate and record buttons, the enable switch
/// (libgpiod).
struct GpioOptions {
  bool enabled = false;
  std::string chip = "gpiochip0";  // name or path
  /// A line by offset ("17") or by name ("GPIO17"); "" = not used.
  std::string status_line, fault_line, calibrate_button, record_button;
  /// Hold-to-run: the drive follows the face only while this input is active.
  std::string enable_switch;
  bool buttons_active_low = true;  // buttons and the enable switch pull the line to ground
  /// The inputs' bias in the chip (GpioBias); auto: towards the released level, where the
  /// kernel can set it, so that an open input reads released.
  GpioBias input_bias = GpioBias::kAuto;
  int debounce_ms = 30;
};

struct Config {
  std::filesystem::path file;  // where it was loaded from, for messages

  spdlog::level::level_enum log_level = spdlog::level::info;

  struct Model {
    std::filesystem::path file = default_model_path();
    LandmarkSet landmark_set = LandmarkSet::F5;
    int iterations = FitSettings{}.iterations;
    /// A model with expression shapes and no calibrated identity fits one on its first this many
    /// tracked frames (AutoIdentity); 0 = the mean face until calibrated.
    int auto_identity_frames = 20;
  } model;

  struct Tracker {
    std::filesystem::path predictor = default_predictor_path();
    /// The face tracker's: `min_face_px` from the file, the rest as TrackerSettings sets them.
    TrackerSettings settings;
  } tracker;

  struct Camera {
    enum class Type { kSim, kV4l2, kLibcamera };
    Type type = Type::kSim;
    SimulatedCameraOptions sim;  // input resolved: never empty
    V4l2Options v4l2;
    std::string libcamera_id;  // "" = the first camera; size and rate as for v4l2
    /// A libcamera camera not there when it is opened is waited for (ConfigUse::kDaemon), else an
    /// error (kCalibrateCamera), as a V4L2 camera's device node is required when the file loads.
    bool wait_when_absent = true;
    Rotation rotation = Rotation::k0;  // the clockwise turn that stands its frames upright
  } camera;

  std::optional<Camera> side_camera;  // [side_camera] when enabled
  /// [side_camera]'s, enabled or not: `process --side` reads a side recording with them too.
  ProfileFacing side_facing = ProfileFacing::kRight;
  Rotation side_rotation = Rotation::k0;

  struct Recording {
    std::filesystem::path dir = "/var/lib/lipdrive/takes";
    bool start = false;
    int flush_interval_ms = 500;
  } recording;

  struct Status {
    int print_interval_ms = 1000;  // 0 = off
  } status;

  struct Scheduling {
    int realtime_priority = 0;  // the frame path's threads under SCHED_FIFO, 1..99; 0 = off
    int cpu_latency_us = -1;    // PM QoS: the CPUs' wake-up latency while the frame path runs; -1 = the system's
    int warm_ahead_us = 2000;   // the predictor's data read into the cache this long before a frame is due; 0 = off
  } scheduling;

  struct Performer {
    std::string name;                                                   // "" = uncalibrated defaults
    std::filesystem::path profiles_dir = "/var/lib/lipdrive/profiles";  // <profiles_dir>/<name>.toml
    int neutral_frames = 30;                                            // tracked frames of a neutral capture
  } performer;

  SafetySettings safety;
  std::vector<ChannelSpec> channels;

  /// [timecode]: what every frame is stamped with (docs/timecode.md).
  struct Timecode {
    enum class Source { kNone, kClock, kLtc };
    Source source = Source::kNone;
    TimecodeRate rate = TimecodeRate::k25;
    /// LTC: from a sound card input, or the generated signal of sim/ltc_generator.hpp.
    enum class Input { kSim, kAlsa };
    Input input = Input::kSim;
    AlsaCaptureOptions alsa{.sample_rate = 48000, .period_frames = 480, .must_open = false};
    SimulatedLtcOptions sim{.sample_rate = 48000, .start = {10, 0, 0, 0}};
  } timecode;

  /// [voice]: the performer's voice drives the mouth while the face is lost (docs/voice.md).
  struct Voice {
    bool enabled = false;
    std::filesystem::path model;  // the performer's voice model (.lpv, `lipdrive voice train`)
    /// The microphone: a sound card input, or the sound of the simulated camera's clip played
    /// in step with its video.
    enum class Input { kSim, kAlsa };
    Input input = Input::kSim;
    /// The sound card's device and channel; its sample_rate is either input's.
    AlsaCaptureOptions alsa{.sample_rate = 16000, .period_frames = 160, .must_open = false};
    int crossfade_ms = 150;      // video <-> voice
    int audio_timeout_ms = 200;  // no sound for this long: the voice is gone (the fail-safe drives)
  } voice;

  /// [osc_control]: remote commands over OSC (docs/osc.md).
  struct OscControl {
    bool enabled = false;
    std::string address = "127.0.0.1";  // the interface bound; "0.0.0.0" for every one
    int port = 8000;
  } osc_control;

  /// [monitor]: the operator's page (docs/monitor.md).
  struct Monitor {
    bool enabled = false;
    std::string address = "127.0.0.1";  // the interface listened on; "0.0.0.0" for every one
    int port = 8480;
    std::string token;       // the control token; "" = a new one at start, logged
    int preview_fps = 10;    // previews a second at most
    int preview_size = 640;  // a preview's width and height at most, pixels (the frame is decimated to fit)
    int max_clients = 4;     // connections served at once (as many more wait; beyond: 503)
  } monitor;

  struct Outputs {
    std::vector<ModbusServerOptions> modbus_servers;
    std::vector<ModbusClientOptions> modbus_clients;
    std::vector<SerialOutputOptions> serial;
    std::vector<DmxOutputOptions> dmx;
    std::vector<OscOutputOptions> osc;
    GpioOptions gpio;
  } outputs;
};

/// What the configuration is loaded for, which decides what must exist when it loads: the
/// cameras' sources (v4l2 devices, sim clips) only where the cameras are used, the profile
/// [performer] names except where `lipdrive calibrate` writes it. Every other key is checked
/// in every use.
enum class ConfigUse {
  kDaemon,           // `run`, `check-config`: the replayed recordings and the profile (cameras are waited for)
  kCalibrateCamera,  // `calibrate` on the configured camera: the replayed recordings and the cameras
  kCalibrateInput,   // `calibrate --input`: a recording stands in for the camera
  kOffline,          // `process`, `voice train`, `voice eval`: recordings; the profile
};

/// Reads and validates a configuration file. Throws ConfigError naming the file, the key
/// and the reason.
Config load_config(const std::filesystem::path& file, ConfigUse use = ConfigUse::kDaemon);

}  // namespace lipdrive
