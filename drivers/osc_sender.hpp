// OSC bundles over UDP: liblo builds and serialises them, a UdpSocket sends them without
// blocking.
//
// Thread model: one owner thread. liblo allocates each message of a bundle on the heap, so
// an owner in a bounded-latency loop gives the sender a thread of its own.
#pragma once

#include "drivers/udp_socket.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace lipdrive {

/// An OSC time tag (NTP format: seconds since 1900 and a 2^-32 s fraction) of a moment given
/// in nanoseconds since the Unix epoch.
struct OscTimeTag {
  std::uint32_t seconds = 0, fraction = 0;
};
OscTimeTag osc_time_tag(std::int64_t unix_time_ns);

class OscSender {
 public:
  /// Resolves `host` (a name or a numeric address) once, here. Throws UdpError.
  OscSender(const std::string& host, int port);
  ~OscSender();
  OscSender(const OscSender&) = delete;
  OscSender& operator=(const OscSender&) = delete;

  /// Starts a new bundle (dropping one not sent).
  void begin_bundle(OscTimeTag time_tag);
  void add(const char* address, float value);
  void add(const char* address, std::int32_t value);
  void add(const char* address, const char* value);
  /// Sends the bundle as one datagram, without blocking. False when it is larger than a UDP
  /// datagram can be or the kernel refused it (errno: EAGAIN for a full send buffer, ...).
  bool send_bundle();
  std::size_t last_size() const { return last_size_; }

  /// "osc udp 127.0.0.1:9000".
  std::string describe() const { return "osc udp " + destination_.describe(); }

 private:
  UdpEndpoint destination_;
  UdpSocket socket_;
  void* bundle_ = nullptr;            // lo_bundle
  std::vector<std::uint8_t> buffer_;  // one datagram's worth, allocated once
  std::size_t last_size_ = 0;
};

}  // namespace lipdrive
