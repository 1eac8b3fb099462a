// OSC messages received on a UDP port: a UdpSocket bound to the configured address (the
// loopback interface unless told otherwise), each datagram parsed by liblo. Bundles are not
// taken apart: control commands arrive as plain messages.
//
// Thread model: one owner thread calls receive(); the handler runs on it.
#pragma once

#include "drivers/udp_socket.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace lipdrive {

/// One parsed message, valid during the handler call.
class OscMessage {
 public:
  std::string_view address() const { return address_; }
  /// Type tags without the leading ',' ("si", "f", "").
  std::string_view types() const { return types_; }
  int size() const { return static_cast<int>(types_.size()); }
  /// Argument `i` as a number ('i', 'h', 'f', 'd'; 'T' 1, 'F' 0); nullopt for other types.
  std::optional<double> number(int i) const;
  /// Argument `i` as a string ('s', 'S'); nullopt for other types.
  std::optional<std::string_view> string(int i) const;

 private:
  friend class OscReceiver;
  std::string_view address_, types_;
  void* const* argv_ = nullptr;  // lo_arg**
};

class OscReceiver {
 public:
  /// Binds `host`:`port` (port 0 picks a free one). Throws UdpError naming the address.
  OscReceiver(const std::string& host, int port);

  enum class Received { kNothing, kMessage, kBundle, kMalformed };
  /// Waits up to `timeout` for one datagram; a well-formed message is passed to `handle`.
  /// `from` is set to the sender's address.
  Received receive(std::chrono::milliseconds timeout, const std::function<void(const OscMessage&)>& handle,
                   std::string* from = nullptr);

  int port() const;
  /// "udp 127.0.0.1:8000".
  std::string describe() const { return "udp " + local_.describe(); }

 private:
  UdpSocket socket_;
  UdpEndpoint local_;
  std::array<std::uint8_t, 65'536> buffer_{};
};

}  // namespace lipdrive
