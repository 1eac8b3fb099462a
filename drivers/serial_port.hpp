// A serial line (UART, USB CDC/FTDI adapter, RS-485 transceiver, pty) opened for writing
// without ever blocking the caller.
//
// Thread model: one owner thread makes every call (construction, write_some, destruction).
// No threads, no locks. The device is opened O_NONBLOCK and stays so: a write takes what
// fits in the kernel's queue and returns; it never waits for the line.
//
// Vanishing devices: a USB adapter unplugged, a pty whose other side closed, a tty hung up
// all make writes fail with EIO/ENXIO/ENODEV/EBADF/EPIPE; write_some reports them as kGone.
// The port object is then useless: the owner destroys it and opens a new one (with back-off)
// when it wants to try again. Keeping reopening out of this class keeps it a plain owner of its fd.
#pragma once

#include "drivers/unique_fd.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

namespace lipdrive {

/// Line settings, independent of the configuration layer (drivers never include it).
struct SerialPortSettings {
  std::string device;  // /dev/ttyUSB0, /dev/serial/by-id/..., a pty link
  int baud = 115200;   // one of kSupportedBauds
  char parity = 'N';   // 'N', 'E' or 'O'
  int data_bits = 8;   // 5..8
  int stop_bits = 1;   // 1 or 2
  bool rs485 = false;  // ask the driver to switch the transceiver direction (TIOCSRS485)
};

inline constexpr int kSupportedBauds[] = {1200,   2400,   4800,   9600,   19200,  38400,  57600,
                                          115200, 230400, 460800, 500000, 576000, 921600, 1000000};

/// Throws std::invalid_argument naming the setting, the value and what is accepted. The
/// configuration loader can call it so that a typo is reported before anything starts.
void validate_serial_settings(const SerialPortSettings& settings);

/// "/dev/ttyUSB0 115200 8N1" (+ " rs485"), for logs and Output::describe().
std::string describe_serial_settings(const SerialPortSettings& settings);

/// Opening failed: the message names the device, the step and the OS reason.
class SerialPortError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class SerialPort {
 public:
  enum class WriteStatus {
    kWritten,     // `written` bytes were queued (possibly fewer than offered: the queue is full)
    kWouldBlock,  // nothing fits right now (EAGAIN); the caller drops or retries later
    kGone,        // the device vanished or hung up; `error` holds errno
  };
  struct WriteResult {
    WriteStatus status = WriteStatus::kWritten;
    std::size_t written = 0;
    int error = 0;
  };

  /// Opens (O_NOCTTY|O_NONBLOCK|O_CLOEXEC), sets raw mode and the line settings, discards
  /// stale queued bytes. Throws std::invalid_argument for invalid settings and
  /// SerialPortError when the device cannot be opened or is not a terminal. An RS-485
  /// request the driver refuses does not fail the open (auto-direction transceivers need
  /// none): rs485_active() is false and rs485_refusal() says why, for the owner to log.
  explicit SerialPort(const SerialPortSettings& settings);
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  /// One non-blocking write(2); retries only on EINTR.
  WriteResult write_some(std::span<const std::uint8_t> bytes);

  /// Bytes written but not yet sent on the line (TIOCOUTQ); 0 where the driver does not say
  /// (ptys). Lets the owner keep the queue, and so the latency, short.
  std::size_t queued_bytes() const;

  bool rs485_active() const { return rs485_active_; }
  const std::string& rs485_refusal() const { return rs485_refusal_; }
  const SerialPortSettings& settings() const { return settings_; }

 private:
  SerialPortSettings settings_;
  UniqueFd fd_;
  bool rs485_active_ = false;
  std::string rs485_refusal_;
};

}  // namespace lipdrive
