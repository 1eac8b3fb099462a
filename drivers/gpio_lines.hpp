// GPIO lines of one chip (status lamps, buttons) behind a small interface, and its
// implementation over libgpiod 1.6 (the v1 C++ API that Debian 12 ships).
//
// Lines are named the way the configuration names them: an offset on the chip ("17") or a
// line name from the device tree ("GPIO17"). All lines are requested when the chip is
// opened, under the consumer name "lipdrive", and released together when it is closed.
//
// Thread model: one thread owns a GpioLines and makes every call on it. No call blocks:
// setting and reading a line are single ioctls on the chip's line handles.
#pragma once

#include <array>
#include <bitset>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

/// Any GPIO failure: the message names the chip, the line and the reason.
class GpioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class GpioDirection { kOutput, kInput };

/// The chip's own resistor on an input, which holds the line where nothing drives it (an open
/// contact, a cut cable); libgpiod's bias flags, Linux 5.5 or later. kAuto: towards the line's
/// inactive level (a pull-up for an active-low input), and left off with a warning naming the
/// line where the kernel cannot set it. kPullUp, kPullDown, kDisable: exactly that, and a
/// request the kernel cannot meet fails (GpioError). kAsIs: as the board and its device tree
/// set it.
enum class GpioBias { kAuto, kPullUp, kPullDown, kDisable, kAsIs };
/// Their names in the configuration ([outputs.gpio] input_bias), in GpioBias order.
inline constexpr std::array<std::string_view, 5> kGpioBiasNames{"auto", "pull-up", "pull-down", "disable", "as-is"};

struct GpioLineSpec {
  std::string line;  // offset ("17") or name ("GPIO17")
  GpioDirection direction = GpioDirection::kOutput;
  /// The line is active (reads or drives true) at low voltage: buttons that pull to ground.
  bool active_low = false;
  GpioBias bias = GpioBias::kAsIs;  // inputs only
};

/// libgpiod v1's request flags (gpiod::line_request::FLAG_*) for `spec`: active-low, and the
/// bias of an input.
std::bitset<32> gpiod_request_flags(const GpioLineSpec& spec);

/// The seam between the GPIO logic and the hardware; tests use a fake.
class GpioLines {
 public:
  virtual ~GpioLines() = default;
  /// Drives an output line to its active (true) or inactive level. Throws GpioError.
  virtual void set_output(const std::string& line, bool active) = 0;
  /// Whether an input line is at its active level. Throws GpioError.
  virtual bool read_input(const std::string& line) = 0;
  /// Releases everything and opens the chip and requests the lines again, e.g. after the
  /// chip went away (USB GPIO expander unplugged). Outputs restart inactive. Throws GpioError
  /// and then holds nothing; a later reopen() may succeed.
  virtual void reopen() = 0;
  /// For logs, e.g. "gpio gpiochip0".
  virtual std::string describe() const = 0;
};

/// The lines of a real chip through libgpiod. `chip`: a name ("gpiochip0"), a path
/// ("/dev/gpiochip0"), a label or a number, as gpiodetect shows them. Opens the chip and
/// requests every line (outputs start inactive); throws GpioError naming the chip and the
/// line (no such chip, not a GPIO chip, no such line, line busy).
std::unique_ptr<GpioLines> open_gpiod_chip(const std::string& chip, std::vector<GpioLineSpec> lines);

/// Opens the chip and looks every line up without requesting it (`lipdrive check-config`):
/// throws GpioError as open_gpiod_chip() would for a missing chip, a device that is no GPIO
/// chip, a line that is not there or one another program holds. A line held under lipdrive's
/// own consumer name (the running daemon) passes.
void check_gpiod_chip(const std::string& chip, const std::vector<GpioLineSpec>& lines);

}  // namespace lipdrive
