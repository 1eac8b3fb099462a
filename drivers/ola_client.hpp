// DMX512 universes to olad, the Open Lighting Architecture daemon (libola's
// StreamingClient). olad runs beside lipdrive on the same host and carries the universe on
// to wherever it is patched: sACN (E1.31), Art-Net, USB DMX widgets. It also merges
// sources by priority, so a console can take over the same universe.
//
// Thread model: one owner thread calls everything. send() writes to libola's non-blocking
// loopback TCP socket: when olad stops reading, the kernel's buffers fill (about 7,000
// universes) and the send that finds no room fails (tests/test_dmx.cpp). connect() is a
// blocking TCP connect to 127.0.0.1. Connecting, sending and the DmxBuffer copy allocate
// (libola and protobuf), on that thread.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace ola {
class DmxBuffer;
namespace client {
class StreamingClient;
}
}  // namespace ola

namespace lipdrive {

/// olad's RPC port unless it is started with --rpc-port.
inline constexpr int kOlaDefaultRpcPort = 9010;

class OlaDmxClient {
 public:
  /// Does not connect yet.
  explicit OlaDmxClient(int rpc_port = kOlaDefaultRpcPort);
  ~OlaDmxClient();
  OlaDmxClient(const OlaDmxClient&) = delete;
  OlaDmxClient& operator=(const OlaDmxClient&) = delete;

  /// Connects to olad on 127.0.0.1:rpc_port; false when olad is not there. Never starts olad.
  bool connect();
  bool connected() const { return client_ != nullptr; }
  void disconnect();

  /// Sends `slots` (slot 1 first, at most 512) to `universe` with a source priority
  /// (0..200, 100 is the default of every source). False, and disconnected, when olad has
  /// gone away, refused the data or stopped reading (its socket's buffers are full).
  bool send(unsigned universe, std::span<const std::uint8_t> slots, std::uint8_t priority);

  /// "olad 127.0.0.1:9010".
  std::string describe() const;
  /// Why the last connect() or send() failed.
  const std::string& last_error() const { return last_error_; }

 private:
  int rpc_port_;
  std::unique_ptr<ola::client::StreamingClient> client_;  // null while disconnected
  std::unique_ptr<ola::DmxBuffer> buffer_;
  std::string last_error_;
};

}  // namespace lipdrive
