// OSC control datagrams ([osc_control], docs/osc.md): what any host that reaches the control
// port sends. The daemon's own OscControl, bound on loopback, gets the fuzzer's bytes as one
// datagram and parses (liblo) and acts on them on its own thread, as in the daemon; the
// commands it understands write a DriveControl and the slate and take. A marker datagram
// sent after the input (a /Slate of its own) tells when the input has been handled, so a
// crash on the control thread is charged to the right input.
#include "drivers/udp_socket.hpp"
#include "firmware_app/daemon/osc_control.hpp"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace lipdrive;

/// One OSC message with a single string argument: address, ",s", the string, each padded
/// with zeros to a multiple of 4 bytes.
std::vector<std::uint8_t> slate_message(const std::string& slate) {
  std::vector<std::uint8_t> bytes;
  const auto put = [&](const std::string& text) {
    bytes.insert(bytes.end(), text.begin(), text.end());
    bytes.resize((bytes.size() / 4 + 1) * 4, 0);
  };
  put("/Slate");
  put(",s");
  put(slate);
  return bytes;
}

struct Quiet {
  Quiet() { spdlog::set_level(spdlog::level::off); }
};

struct Peer {
  Quiet quiet;
  DriveControl drive;
  OscControl control{"127.0.0.1", 0, drive};
  UdpEndpoint to = resolve_udp("127.0.0.1", control.port());
  UdpSocket sender = UdpSocket::for_sending(to);
  unsigned long inputs = 0;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Peer peer;
  // UDP over IPv4 carries at most 65,507 bytes; an empty datagram is no message.
  if (size == 0 || size > 65'507 || !peer.sender.send_to({data, size}, peer.to)) return 0;
  const std::string marker = "fuzzmarker" + std::to_string(++peer.inputs);
  if (!peer.sender.send_to(slate_message(marker), peer.to)) std::abort();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  for (;;) {
    const std::optional<std::string> take = peer.control.next_take_name();
    if (take && take->starts_with(marker + "_")) break;
    if (std::chrono::steady_clock::now() > deadline) std::abort();  // the control thread hangs
    std::this_thread::yield();
  }
  return 0;
}
