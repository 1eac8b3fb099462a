// A UDP socket (POSIX sockets) for the OSC output and the OSC control input: numeric or
// named hosts resolved once with getaddrinfo, IPv4 or IPv6, sends that never block.
//
// Thread model: one owner thread per socket.
#pragma once

#include "drivers/unique_fd.hpp"

#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

namespace lipdrive {

/// A host that does not resolve, a port that cannot be bound; the message names the host
/// and the reason.
class UdpError : public std::runtime_error {
 public:
  explicit UdpError(const std::string& what, bool temporary = false)
      : std::runtime_error(what), temporary_(temporary) {}
  /// No name server answered (getaddrinfo's EAI_AGAIN), as at boot before the network is up:
  /// asking again later may succeed, where a name the server does not know will not.
  bool temporary() const { return temporary_; }

 private:
  bool temporary_;
};

struct UdpEndpoint {
  sockaddr_storage address{};
  socklen_t length = 0;
  /// "127.0.0.1:9000", "[::1]:9000".
  std::string describe() const;
};

/// Resolves `host` (a name or a numeric address) and `port` for UDP, to the address
/// preferred_address() picks. Throws UdpError.
UdpEndpoint resolve_udp(const std::string& host, int port);

/// Of getaddrinfo's answers for a name (a non-empty list), the first IPv4 address, else the
/// first. Debian's /etc/hosts gives `localhost` the address ::1 as well as 127.0.0.1 and
/// getaddrinfo may sort ::1 first, while show-control peers (and liblo's servers) mostly
/// listen on IPv4 alone: "localhost" must reach them.
const addrinfo& preferred_address(const addrinfo& found);

class UdpSocket {
 public:
  /// An unbound socket for sending to endpoints of `destination`'s address family. Throws
  /// UdpError.
  static UdpSocket for_sending(const UdpEndpoint& destination);
  /// A socket bound to `local` (port 0 picks a free one). Throws UdpError naming the
  /// address ("Address already in use", "Cannot assign requested address").
  static UdpSocket bound(const UdpEndpoint& local);

  /// Sends one datagram without blocking; false with errno set when the kernel refused it
  /// (buffer full: EAGAIN; no route: ENETUNREACH ...).
  bool send_to(std::span<const std::uint8_t> datagram, const UdpEndpoint& destination) const;
  /// Waits up to `timeout` for a datagram and copies what fits of it to `buffer`. Returns
  /// the datagram's full size (larger than the buffer: it was cut), or 0 when none
  /// arrived. `from`, when given, receives the sender.
  std::size_t receive(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout, UdpEndpoint* from) const;
  /// The bound address (with the port actually bound).
  UdpEndpoint local() const;

 private:
  explicit UdpSocket(UniqueFd fd) : fd_(std::move(fd)) {}
  UniqueFd fd_;
};

}  // namespace lipdrive
