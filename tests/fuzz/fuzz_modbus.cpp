// Modbus requests, through the server's own request handling: the register map's server
// (ModbusServerOutput on a ModbusServer thread, TCP on loopback) gets the fuzzer's bytes as
// one client connection, answers what it can parse, and must drop the rest without harm; the
// control registers it writes go to a DriveControl as in the daemon. A crash on the server
// thread ends the fuzzer like one on its own thread.
#include "firmware_app/outputs/modbus_server_output.hpp"

#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <memory>
#include <vector>

namespace {

using namespace lipdrive;

struct Server {
  Server() {
    spdlog::set_level(spdlog::level::off);
    ModbusServerOptions options;
    options.link.port = 0;  // any free port
    options.max_clients = 2;
    output = std::make_unique<ModbusServerOutput>(options, channels, control);
    DriveFrame frame;
    frame.channel_count = static_cast<int>(channels.size());
    frame.values[0] = 123;
    output->publish(frame);
  }
  std::vector<ChannelSpec> channels = {{.name = "open", .signal = Signal::kOpen, .out_min = 0, .out_max = 1000},
                                       {.name = "width", .signal = Signal::kWidth, .out_min = 0, .out_max = 1000}};
  DriveControl control;
  std::unique_ptr<ModbusServerOutput> output;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Server server;
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(server.output->port()));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
    for (std::size_t sent = 0; sent < size;) {
      const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += static_cast<std::size_t>(n);
    }
    // No more requests: the server answers what it has and drops the connection at the end
    // of the bytes (or earlier, at the first that is not a request).
    ::shutdown(fd, SHUT_WR);
    std::uint8_t reply[512];
    pollfd readable{fd, POLLIN, 0};
    while (::poll(&readable, 1, 1000) == 1 && ::recv(fd, reply, sizeof reply, 0) > 0) {
    }
  }
  ::close(fd);
  return 0;
}
