// OSC bundles over UDP: liblo lays a bundle out once, every frame writes its values into
// those bytes, a UdpSocket sends them without blocking. Nothing allocates per frame.
//
// Thread model: an OscBundle and an OscSender each have one owner thread.
#pragma once

#include "drivers/udp_socket.hpp"

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

/// An OSC time tag (NTP format: seconds since 1900 and a 2^-32 s fraction) of a moment given
/// in nanoseconds since the Unix epoch.
struct OscTimeTag {
  std::uint32_t seconds = 0, fraction = 0;
};
OscTimeTag osc_time_tag(std::int64_t unix_time_ns);

/// A bundle whose layout is fixed when it is made: each message has one argument of a fixed
/// type, a string one of a fixed length. liblo builds and serialises it once, here; setting a
/// value afterwards writes only that argument's bytes (OSC 1.0: 32-bit big-endian numbers,
/// strings NUL-padded to a multiple of 4), so a frame's bundle costs no allocation and its
/// bytes are exactly what liblo would serialise for the same values (tests/test_osc.cpp).
class OscBundle {
 public:
  enum class Type : char { kInt32 = 'i', kFloat = 'f', kString = 's' };
  struct Message {
    std::string address;
    Type type = Type::kFloat;
    std::size_t string_length = 0;  // kString: the length of every value it will carry
  };
  /// Throws std::invalid_argument when the bundle would not fit in one UDP datagram.
  explicit OscBundle(std::span<const Message> messages);

  void set_time_tag(OscTimeTag time_tag);
  /// The value of message `index`, which must have the matching type; a string is cut or
  /// padded with spaces to the message's length.
  void set(std::size_t index, float value);
  void set(std::size_t index, std::int32_t value);
  void set(std::size_t index, std::string_view value);

  std::span<const std::uint8_t> bytes() const { return bytes_; }
  std::size_t size() const { return argument_offsets_.size(); }

 private:
  std::vector<std::uint8_t> bytes_;
  std::vector<std::size_t> argument_offsets_;
  std::vector<Message> messages_;
};

class OscSender {
 public:
  /// Resolves `host` (a name or a numeric address) once, here. Throws UdpError.
  OscSender(const std::string& host, int port);
  OscSender(const OscSender&) = delete;
  OscSender& operator=(const OscSender&) = delete;

  /// Sends the bundle as one datagram, without blocking. False when the kernel refused it
  /// (errno: EAGAIN for a full send buffer, ...).
  bool send(const OscBundle& bundle);

  /// "osc udp 127.0.0.1:9000".
  std::string describe() const { return "osc udp " + destination_.describe(); }

 private:
  UdpEndpoint destination_;
  UdpSocket socket_;
};

}  // namespace lipdrive
