// The GPIO output (docs/data-flow.md): a status line (tracking OK), a fault line, the
// calibrate and record buttons, and the enable switch.
//
// Lines: status is active while the newest frame is tracked and the fail-safe is off; fault
// is active while the fail-safe holds the channels of an enabled drive or the camera delivers
// nothing (the fail-safe only engages after its hold time; an unplugged camera shows at once;
// a drive disabled on purpose, by the command or the enable switch, is no fault). Output
// lines are written only when their level changes.
//
// Buttons are sampled on every publish(), which the output thread calls for every result
// and on idle ticks (at least 50 Hz), and debounced on the frame's CLOCK_MONOTONIC time.
// A calibrate press adds one calibrate request; a record press asks to stop a take when the
// frame's status word reports one recording and to start one otherwise.
//
// The enable switch is hold-to-run: DriveControl::enable_switch_closed follows its debounced
// level, and the drive eases to neutral while it is open. It reads open from construction
// until its first sample, and while its chip is lost: a switch that cannot be read does not
// let the figure move.
//
// Errors: a failing line (chip unplugged, driver error) is logged once, healthy() turns
// false and the chip is reopened with exponential back-off (core/backoff.hpp, 100 ms up to
// 5 s) on later publish() calls; on success it is logged, the outputs are written afresh and
// the buttons start over (a button held across the outage is not a press). publish() never
// throws.
//
// Thread model: the output thread makes every call except healthy() and describe(), which
// any thread may call.
#pragma once

#include "core/backoff.hpp"
#include "drivers/gpio_lines.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/outputs/debouncer.hpp"
#include "firmware_app/outputs/output.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lipdrive {

/// The configured lines: status and fault as outputs, the buttons and the enable switch as
/// inputs, active-low if `buttons_active_low`, with `input_bias`; unused lines ("") are left
/// out.
std::vector<GpioLineSpec> gpio_line_specs(const GpioOptions& options);
/// Opens `options.chip` and requests gpio_line_specs(options). Throws GpioError naming the
/// chip and the line.
std::unique_ptr<GpioLines> open_gpio_chip(const GpioOptions& options);
/// Looks up the chip and the configured lines without requesting them (check_gpiod_chip).
void check_gpio_chip(const GpioOptions& options);

class GpioOutput final : public Output {
 public:
  /// `lines` must hold every line `options` names (open_gpio_chip(options) does); `control`
  /// must outlive the output. Touches no line until the first publish().
  GpioOutput(const GpioOptions& options, std::unique_ptr<GpioLines> lines, DriveControl& control);

  void publish(const DriveFrame& frame) override;
  /// E.g. "gpio gpiochip0 (status 17, fault 27, calibrate GPIO22, record GPIO23)".
  std::string describe() const override { return description_; }
  bool healthy() const override { return healthy_.load(std::memory_order_relaxed); }

 private:
  struct OutputLine {
    std::string line;             // "" = not used
    std::optional<bool> written;  // the level last written; none = unknown, write it
  };
  struct Button {
    std::string line;  // "" = not used
    Debouncer debouncer;
  };

  void write(OutputLine& output, bool active);
  bool pressed(Button& button, std::int64_t now_ns);
  /// `recording`: the frame's status word says a take is being recorded.
  void poll_buttons(std::int64_t now_ns, bool recording);
  void poll_enable_switch(std::int64_t now_ns);
  /// Tells the pipeline whether the enable switch is closed, and logs a change (`why` it is not).
  void set_enable_switch(bool closed, const char* why);
  void lose_lines(const char* error, std::int64_t now_ns);
  bool reopen_lines(std::int64_t now_ns);

  std::unique_ptr<GpioLines> lines_;
  DriveControl& control_;
  std::string description_;
  OutputLine status_, fault_;
  Button calibrate_, record_, enable_;

  std::atomic<bool> healthy_{true};
  Backoff retry_;  // reopening the chip after its lines were lost
  std::int64_t next_retry_ns_ = 0;
};

}  // namespace lipdrive
