#include "drivers/serial_port.hpp"

#include <fcntl.h>
#include <linux/serial.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string_view>

namespace lipdrive {
namespace {

speed_t baud_constant(int baud) {
  switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 576000: return B576000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    default: break;
  }
  std::string accepted;
  for (int supported : kSupportedBauds) accepted += (accepted.empty() ? "" : ", ") + std::to_string(supported);
  throw std::invalid_argument("serial baud " + std::to_string(baud) + " is not supported (accepted: " + accepted + ")");
}

tcflag_t data_bits_flag(int bits) {
  switch (bits) {
    case 5: return CS5;
    case 6: return CS6;
    case 7: return CS7;
    case 8: return CS8;
    default:
      throw std::invalid_argument("serial data bits " + std::to_string(bits) + " is not supported (accepted: 5..8)");
  }
}

[[noreturn]] void throw_os_error(const SerialPortSettings& settings, std::string_view step, int error) {
  throw SerialPortError("serial " + settings.device + ": " + std::string(step) + ": " + std::strerror(error));
}

}  // namespace

void validate_serial_settings(const SerialPortSettings& settings) {
  if (settings.device.empty()) throw std::invalid_argument("serial device is empty");
  baud_constant(settings.baud);
  data_bits_flag(settings.data_bits);
  if (settings.parity != 'N' && settings.parity != 'E' && settings.parity != 'O')
    throw std::invalid_argument(std::string("serial parity '") + settings.parity +
                                "' is not supported (accepted: N, E, O)");
  if (settings.stop_bits != 1 && settings.stop_bits != 2)
    throw std::invalid_argument("serial stop bits " + std::to_string(settings.stop_bits) +
                                " is not supported (accepted: 1, 2)");
}

std::string describe_serial_settings(const SerialPortSettings& settings) {
  return settings.device + " " + std::to_string(settings.baud) + " " + std::to_string(settings.data_bits) +
         settings.parity + std::to_string(settings.stop_bits) + (settings.rs485 ? " rs485" : "");
}

SerialPort::SerialPort(const SerialPortSettings& settings) : settings_(settings) {
  validate_serial_settings(settings_);
  fd_ = UniqueFd(::open(settings_.device.c_str(), O_WRONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
  if (!fd_.valid()) throw_os_error(settings_, "cannot open", errno);
  const int fd = fd_.get();
  // A throw from here on closes the descriptor with fd_.
  termios options{};
  if (::tcgetattr(fd, &options) != 0) throw_os_error(settings_, "not a serial line", errno);
  ::cfmakeraw(&options);
  options.c_cflag &= ~(CSIZE | PARENB | PARODD | CSTOPB | CRTSCTS | HUPCL);
  // CLOCAL: no modem control. Without it a missing DCD on an RS-232 adapter hangs the line up.
  options.c_cflag |= CLOCAL | CREAD | data_bits_flag(settings_.data_bits);
  if (settings_.parity != 'N') options.c_cflag |= PARENB | (settings_.parity == 'O' ? PARODD : 0);
  if (settings_.stop_bits == 2) options.c_cflag |= CSTOPB;
  options.c_cc[VMIN] = 0;
  options.c_cc[VTIME] = 0;
  const speed_t speed = baud_constant(settings_.baud);
  ::cfsetispeed(&options, speed);
  ::cfsetospeed(&options, speed);
  if (::tcsetattr(fd, TCSANOW, &options) != 0) throw_os_error(settings_, "cannot set line settings", errno);
  // Bytes a previous owner left in the queue are stale values: never send them.
  ::tcflush(fd, TCIOFLUSH);

  if (settings_.rs485) {
    serial_rs485 rs485{};
    // RTS high while sending drives the transceiver's DE pin; low again after the last bit.
    rs485.flags = SER_RS485_ENABLED | SER_RS485_RTS_ON_SEND;
    if (::ioctl(fd, TIOCSRS485, &rs485) == 0) {
      rs485_active_ = true;
    } else {
      rs485_refusal_ = std::strerror(errno);
    }
  }
}

SerialPort::WriteResult SerialPort::write_some(std::span<const std::uint8_t> bytes) {
  ssize_t result;
  do {
    result = ::write(fd_.get(), bytes.data(), bytes.size());
  } while (result < 0 && errno == EINTR);
  if (result >= 0) return {WriteStatus::kWritten, static_cast<std::size_t>(result), 0};
  const int error = errno;
  if (error == EAGAIN || error == EWOULDBLOCK) return {WriteStatus::kWouldBlock, 0, error};
  // EIO/ENXIO/ENODEV/EBADF/EPIPE are a vanished or hung-up device; anything else leaves the
  // line in an unknown state too, so the owner reopens either way and logs the reason.
  return {WriteStatus::kGone, 0, error};
}

std::size_t SerialPort::queued_bytes() const {
  int queued = 0;
  if (::ioctl(fd_.get(), TIOCOUTQ, &queued) != 0) return 0;
  return static_cast<std::size_t>(std::max(queued, 0));
}

}  // namespace lipdrive
