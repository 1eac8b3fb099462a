#include "drivers/gpio_lines.hpp"

#include <gpiod.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <system_error>
#include <utility>

namespace lipdrive {
namespace {

constexpr const char* kConsumer = "lipdrive";

/// libgpiod v1 reports failures as std::system_error carrying errno.
int error_code_of(const std::system_error& error) { return error.code().value(); }

/// A kernel before Linux 5.5 rejects the bias flags as unknown (EINVAL); a driver may refuse
/// the setting (EOPNOTSUPP, or the kernel's internal ENOTSUPP, 524).
bool cannot_set_bias(int code) { return code == EINVAL || code == EOPNOTSUPP || code == 524; }

[[noreturn]] void fail(const std::string& chip, const std::string& reason) {
  throw GpioError("gpio chip " + chip + ": " + reason);
}

gpiod::chip open_chip(const std::string& name) {
  gpiod::chip chip;
  try {
    chip.open(name, gpiod::chip::OPEN_LOOKUP);
  } catch (const std::system_error& error) {
    const int code = error_code_of(error);
    if (code == ENOENT) fail(name, "no such chip");
    if (code == ENOTTY || code == EINVAL || code == ENODEV) fail(name, "not a GPIO chip");
    fail(name, "cannot open: " + error.code().message());
  }
  return chip;
}

/// `line`: an offset ("17") or a line name ("GPIO17") on `chip`, opened as `chip_name`.
gpiod::line find_line(const gpiod::chip& chip, const std::string& chip_name, const std::string& line) {
  unsigned offset = 0;
  const char* end = line.data() + line.size();
  if (!line.empty() && std::from_chars(line.data(), end, offset).ptr == end) {
    if (offset >= chip.num_lines())
      fail(chip_name, "line " + line + ": no such offset (the chip has " + std::to_string(chip.num_lines()) + " lines)");
    return chip.get_line(offset);
  }
  gpiod::line found = chip.find_line(line);
  if (!found) fail(chip_name, "no line named \"" + line + "\"");
  return found;
}

/// Lines of a chip opened with libgpiod 1.6: the chip and the requested line handles.
///
/// Closing the chip (dropping its last reference: `chip` and every gpiod::line hold one)
/// releases the lines it requested, so destroying this object is the whole release.
class GpiodChipLines final : public GpioLines {
 public:
  GpiodChipLines(std::string chip, std::vector<GpioLineSpec> lines)
      : chip_name_(std::move(chip)), specs_(std::move(lines)) {
    open();
  }

  void set_output(const std::string& line, bool active) override {
    try {
      requested(line, GpioDirection::kOutput).set_value(active ? 1 : 0);
    } catch (const std::system_error& error) {
      fail("line " + line + ": cannot set: " + error.code().message());
    }
  }

  bool read_input(const std::string& line) override {
    try {
      return requested(line, GpioDirection::kInput).get_value() != 0;
    } catch (const std::system_error& error) {
      fail("line " + line + ": cannot read: " + error.code().message());
    }
  }

  void reopen() override {
    close();
    open();
  }

  std::string describe() const override { return "gpio " + chip_name_; }

 private:
  struct Requested {
    GpioLineSpec spec;
    gpiod::line line;
  };

  [[noreturn]] void fail(const std::string& reason) const { lipdrive::fail(chip_name_, reason); }

  void close() {
    requested_.clear();
    chip_.reset();
  }

  /// Builds the new state in locals and keeps it only when every line was requested: a
  /// failure half-way closes the chip and with it the lines requested so far.
  void open() {
    gpiod::chip chip = open_chip(chip_name_);
    std::vector<Requested> requested;
    try {
      for (const GpioLineSpec& spec : specs_) requested.push_back({spec, request(chip, spec)});
    } catch (const std::system_error& error) {
      // Looking lines up reads the chip's line info, which fails if the chip goes away now.
      fail("cannot look up the lines: " + error.code().message());
    }
    chip_ = std::move(chip);
    requested_ = std::move(requested);
  }

  gpiod::line request(const gpiod::chip& chip, const GpioLineSpec& spec) const {
    gpiod::line line = find_line(chip, chip_name_, spec.line);
    GpioLineSpec as_is = spec;
    as_is.bias = GpioBias::kAsIs;
    const std::bitset<32> flags = gpiod_request_flags(spec), without_bias = gpiod_request_flags(as_is);
    int code = try_request(line, spec, flags);
    if (code != 0 && flags != without_bias && cannot_set_bias(code)) {
      const std::string what = "line " + spec.line + ": the kernel cannot set input_bias \"" +
                               std::string(kGpioBiasNames[static_cast<std::size_t>(spec.bias)]) + "\" (" +
                               std::system_category().message(code) + ")";
      if (spec.bias != GpioBias::kAuto) fail(what + "; input_bias = \"as-is\" leaves it to the board's resistor");
      spdlog::warn("gpio chip {}: {}: it rests on the board's resistor", chip_name_, what);
      code = try_request(line, spec, without_bias);
    }
    if (code == EBUSY) fail("line " + spec.line + ": busy (used by \"" + line.consumer() + "\")");
    if (code != 0) fail("line " + spec.line + ": cannot request: " + std::system_category().message(code));
    return line;
  }

  /// 0, or the errno of a failed request.
  static int try_request(gpiod::line& line, const GpioLineSpec& spec, std::bitset<32> flags) {
    gpiod::line_request config;
    config.consumer = kConsumer;
    config.request_type = spec.direction == GpioDirection::kOutput ? gpiod::line_request::DIRECTION_OUTPUT
                                                                   : gpiod::line_request::DIRECTION_INPUT;
    config.flags = flags;
    try {
      line.request(config, 0);
    } catch (const std::system_error& error) {
      return error_code_of(error);
    }
    return 0;
  }

  const gpiod::line& requested(const std::string& line, GpioDirection direction) const {
    const auto found = std::ranges::find_if(requested_, [&](const Requested& candidate) {
      return candidate.spec.line == line && candidate.spec.direction == direction;
    });
    if (found == requested_.end())
      fail("line " + line + ": not requested as an " + (direction == GpioDirection::kOutput ? "output" : "input") +
           (chip_ ? "" : " (the chip is closed after a failed reopen)"));
    return found->line;
  }

  std::string chip_name_;
  std::vector<GpioLineSpec> specs_;
  gpiod::chip chip_;
  std::vector<Requested> requested_;
};

}  // namespace

std::bitset<32> gpiod_request_flags(const GpioLineSpec& spec) {
  std::bitset<32> flags;
  if (spec.active_low) flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
  if (spec.direction == GpioDirection::kInput) {
    const GpioBias towards_inactive = spec.active_low ? GpioBias::kPullUp : GpioBias::kPullDown;
    switch (spec.bias == GpioBias::kAuto ? towards_inactive : spec.bias) {
      case GpioBias::kPullUp: flags |= gpiod::line_request::FLAG_BIAS_PULL_UP; break;
      case GpioBias::kPullDown: flags |= gpiod::line_request::FLAG_BIAS_PULL_DOWN; break;
      case GpioBias::kDisable: flags |= gpiod::line_request::FLAG_BIAS_DISABLE; break;
      case GpioBias::kAuto:
      case GpioBias::kAsIs: break;
    }
  }
  return flags;
}

std::unique_ptr<GpioLines> open_gpiod_chip(const std::string& chip, std::vector<GpioLineSpec> lines) {
  return std::make_unique<GpiodChipLines>(chip, std::move(lines));
}

void check_gpiod_chip(const std::string& chip, const std::vector<GpioLineSpec>& lines) {
  const gpiod::chip opened = open_chip(chip);
  try {
    for (const GpioLineSpec& spec : lines) {
      const gpiod::line line = find_line(opened, chip, spec.line);
      if (line.is_used() && line.consumer() != kConsumer)
        fail(chip, "line " + spec.line + ": busy (used by \"" + line.consumer() + "\")");
    }
  } catch (const std::system_error& error) {
    fail(chip, "cannot look up the lines: " + error.code().message());
  }
}

}  // namespace lipdrive
