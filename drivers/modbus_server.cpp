#include "drivers/modbus_server.hpp"

#include "core/backoff.hpp"
#include "drivers/thread_scheduling.hpp"

#include <fmt/format.h>
#include <modbus/modbus-tcp.h>
#include <spdlog/spdlog.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <utility>

namespace lipdrive {

namespace {

// A serial line that failed or was not there, or a port that could not be listened on, is
// tried again with back-off, from 100 ms up to 5 s.
constexpr std::chrono::milliseconds kReopenFirst{100}, kReopenMax{5000};
constexpr int kAcceptRetryMs = 100;
// TCP keepalive: a peer that vanished without a FIN (a PLC power-cycled, a cable pulled) is
// found out after about a minute of silence instead of the kernel's two hours.
constexpr int kKeepaliveIdleS = 30, kKeepaliveIntervalS = 10, kKeepaliveProbes = 3;

using SteadyTime = std::chrono::steady_clock::time_point;

/// A TCP client and when it last sent a request (or connected): a full server makes room
/// by closing the quietest one.
struct TcpClient {
  TcpClient(UniqueFd connection, SteadyTime connected) : fd(std::move(connection)), last_request(connected) {}
  UniqueFd fd;
  SteadyTime last_request;
  std::optional<SteadyTime> incomplete_since;  // part of a request is in, since then
  int low_water = 1;                           // the socket's SO_RCVLOWAT
};

// The MBAP header: transaction id, protocol id, length (of what follows it, unit id
// included), unit id. A request's length is 2 (unit id, function code) to 254 (unit id and
// the longest PDU, 253 bytes: an ADU of MODBUS_TCP_MAX_ADU_LENGTH).
constexpr int kMbapLength = 7, kMbapLengthBefore = 6, kMinLengthField = 2, kMaxLengthField = 254;

/// The functions of docs/modbus-register-map.md: the registers', and the bits' (answered with
/// exception 2: the map has no coils or discrete inputs).
bool in_the_map(int function) {
  switch (function) {
    case MODBUS_FC_READ_COILS:
    case MODBUS_FC_READ_DISCRETE_INPUTS:
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS:
    case MODBUS_FC_WRITE_SINGLE_COIL:
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS:
    case MODBUS_FC_MASK_WRITE_REGISTER:
    case MODBUS_FC_WRITE_AND_READ_REGISTERS: return true;
    default: return false;
  }
}

/// What the server thread does next with a client poll() woke it for.
enum class Next { kWait, kAnswer, kDrop };

/// Raises the socket's low-water mark to the bytes a request still needs, so that poll()
/// wakes once it is complete rather than for every byte a slow client sends.
void set_low_water(TcpClient& client, int bytes) {
  if (client.low_water == bytes) return;
  ::setsockopt(client.fd.get(), SOL_SOCKET, SO_RCVLOWAT, &bytes, sizeof bytes);
  client.low_water = bytes;
}

/// Answer only a request that is in the socket whole, by its MBAP length field:
/// modbus_receive() waits on its socket until the frame is complete, and the one server
/// thread would serve nobody else meanwhile (a client sending a byte every 40 ms, under the
/// byte timeout, held every other client, a reload and a stop for seconds).
Next check_request(TcpClient& client, short revents, SteadyTime now) {
  std::uint8_t header[kMbapLength];
  const ssize_t peeked = ::recv(client.fd.get(), header, sizeof header, MSG_PEEK | MSG_DONTWAIT);
  if (peeked == 0) {
    errno = ECONNRESET;  // closed by the peer
    return Next::kDrop;
  }
  if (peeked < 0)
    return (errno == EAGAIN || errno == EINTR) && !(revents & (POLLHUP | POLLERR)) ? Next::kWait : Next::kDrop;
  int needed = kMbapLength;
  if (peeked == kMbapLength) {
    const int length = (header[4] << 8) | header[5];
    if (length < kMinLengthField || length > kMaxLengthField) {
      errno = EMBBADDATA;
      return Next::kDrop;
    }
    needed = kMbapLengthBefore + length;
    int available = 0;
    if (::ioctl(client.fd.get(), FIONREAD, &available) == -1) return Next::kDrop;
    if (available >= needed) {
      set_low_water(client, 1);  // libmodbus reads it, and the next request wakes poll()
      client.incomplete_since.reset();
      return Next::kAnswer;
    }
  }
  if (revents & (POLLRDHUP | POLLHUP | POLLERR)) {
    errno = ECONNRESET;  // the rest will never come
    return Next::kDrop;
  }
  if (!client.incomplete_since) client.incomplete_since = now;
  set_low_water(client, needed);
  return Next::kWait;
}

/// poll()'s timeout: until the first incomplete request's time is up, -1 when there is none.
int poll_timeout_ms(const std::vector<TcpClient>& clients, SteadyTime now) {
  std::optional<SteadyTime> first;
  for (const TcpClient& client : clients)
    if (client.incomplete_since && (!first || *client.incomplete_since < *first)) first = client.incomplete_since;
  if (!first) return -1;
  const auto left = *first + std::chrono::milliseconds(ModbusServer::kRequestTimeoutMs) - now;
  return static_cast<int>(std::max<std::int64_t>(0, std::chrono::ceil<std::chrono::milliseconds>(left).count()));
}

void set_client_options(int fd) {
  const int on = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);  // replies go out at once
  ::setsockopt(fd, SOL_SOCKET, SO_KEEPALIVE, &on, sizeof on);
  ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPIDLE, &kKeepaliveIdleS, sizeof kKeepaliveIdleS);
  ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPINTVL, &kKeepaliveIntervalS, sizeof kKeepaliveIntervalS);
  ::setsockopt(fd, IPPROTO_TCP, TCP_KEEPCNT, &kKeepaliveProbes, sizeof kKeepaliveProbes);
}

/// The holding registers a request writes and the values they get, decoded from the request
/// itself so that the owner hears of a write before the acknowledgement goes out. Empty when
/// the request writes nothing or libmodbus will reject it: the checks mirror modbus_reply(),
/// so a request answered with an exception is never reported as a write.
struct Write {
  int address = 0;
  std::span<const std::uint16_t> values;
};

std::optional<Write> decode_write(const std::uint8_t* pdu, std::span<const std::uint16_t> holding,
                                  std::span<std::uint16_t> buffer) {
  const auto word = [pdu](int at) { return static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]); };
  const auto fits = [&](int address, int count) {
    return count >= 1 && address + count <= static_cast<int>(holding.size());
  };
  // Function 16 and 23 carry `count` values from `first_value` on.
  const auto block = [&](int address, int count, int byte_count_at, int max_count) -> std::optional<Write> {
    if (count > max_count || pdu[byte_count_at] != 2 * count || !fits(address, count)) return std::nullopt;
    for (int i = 0; i < count; ++i) buffer[static_cast<std::size_t>(i)] = word(byte_count_at + 1 + 2 * i);
    return Write{address, buffer.first(static_cast<std::size_t>(count))};
  };
  switch (pdu[0]) {
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
      if (!fits(word(1), 1)) return std::nullopt;
      buffer[0] = word(3);
      return Write{word(1), buffer.first(1)};
    case MODBUS_FC_MASK_WRITE_REGISTER: {
      if (!fits(word(1), 1)) return std::nullopt;
      const std::uint16_t and_mask = word(3), or_mask = word(5);
      buffer[0] = static_cast<std::uint16_t>((holding[word(1)] & and_mask) | (or_mask & ~and_mask));
      return Write{word(1), buffer.first(1)};
    }
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: return block(word(1), word(3), 5, MODBUS_MAX_WRITE_REGISTERS);
    case MODBUS_FC_WRITE_AND_READ_REGISTERS:
      if (word(3) > MODBUS_MAX_WR_READ_REGISTERS || !fits(word(1), word(3))) return std::nullopt;
      return block(word(5), word(7), 9, MODBUS_MAX_WR_WRITE_REGISTERS);
    default: return std::nullopt;
  }
}

void set_timeouts(modbus_t* context, ModbusEndpoint::Transport transport) {
  constexpr std::uint32_t us = ModbusServer::kByteTimeoutMs * 1000;
  modbus_set_byte_timeout(context, 0, us);
  // Requests are only read once poll() saw data, so this only guards against a spurious wake-up.
  modbus_set_indication_timeout(context, 0, us);
  // A server never waits for a response; libmodbus uses this timeout only to sleep before it
  // flushes the line after a request with an illegal count (modbus_reply), and that sleep
  // holds up every client of the server thread (500 ms by default). A TCP request was read
  // whole by its length field, so there is nothing to wait for (1 us, the least libmodbus
  // takes); the rest of a bad serial frame arrives within the byte timeout.
  modbus_set_response_timeout(context, 0, transport == ModbusEndpoint::Transport::kTcp ? 1 : us);
}

}  // namespace

ModbusServer::ModbusServer(const ModbusEndpoint& endpoint, int max_clients, int input_registers, int holding_registers,
                           Refresh refresh, Written written)
    : endpoint_(endpoint),
      max_clients_(max_clients),
      refresh_(std::move(refresh)),
      written_(std::move(written)),
      context_(make_context(endpoint)),
      mapping_(modbus_mapping_new(0, 0, holding_registers, input_registers)),
      wake_fd_(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK)),
      query_(MODBUS_TCP_MAX_ADU_LENGTH) {
  if (!mapping_ || wake_fd_.get() == -1)
    throw std::runtime_error(fmt::format("modbus server {}: {}", describe(), std::strerror(errno)));
  set_timeouts(context_.get(), endpoint.transport);
  // A port taken by another process or a serial device not there yet stops no other output: the
  // server reports itself unhealthy and its thread tries again with back-off.
  const bool tcp = endpoint.transport == ModbusEndpoint::Transport::kTcp;
  if (tcp ? listen() : connect_context(context_.get(), endpoint_)) {
    spdlog::info("modbus server {}: serving {} input and {} holding registers", describe(), input_registers,
                 holding_registers);
  } else {
    const int error = errno;
    spdlog::error("modbus server {}: cannot {}: {}; trying again with back-off up to {} ms", describe(),
                  tcp ? "listen" : "open", modbus_strerror(error), kReopenMax.count());
    healthy_.store(false, std::memory_order_relaxed);
  }
  thread_ = std::thread(tcp ? &ModbusServer::serve_tcp : &ModbusServer::serve_rtu, this);
  name_thread(thread_, "lipdrive-mbserve");
}

ModbusServer::~ModbusServer() {
  stopping_.store(true, std::memory_order_relaxed);
  const std::uint64_t one = 1;
  [[maybe_unused]] const ssize_t ignored = ::write(wake_fd_.get(), &one, sizeof one);
  thread_.join();
  // TCP: the client sockets were the thread's, the listener is listen_fd_'s. RTU: the context's
  // socket is the serial line, which modbus_close() (the context's deleter) closes.
  if (endpoint_.transport == ModbusEndpoint::Transport::kTcp) modbus_set_socket(context_.get(), -1);
}

std::string ModbusServer::describe() const {
  if (const int bound = port(); endpoint_.transport == ModbusEndpoint::Transport::kTcp && bound != 0)
    return fmt::format("tcp {}:{}", endpoint_.address, bound);
  return lipdrive::describe(endpoint_);
}

bool ModbusServer::listen() {
  UniqueFd fd(modbus_tcp_listen(context_.get(), max_clients_));
  sockaddr_in bound{};
  socklen_t size = sizeof bound;
  if (fd.get() == -1 || ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&bound), &size) == -1) return false;
  listen_fd_ = std::move(fd);
  port_.store(ntohs(bound.sin_port), std::memory_order_relaxed);
  return true;
}

short ModbusServer::wait_readable(int fd, int timeout_ms) {
  pollfd fds[2] = {{wake_fd_.get(), POLLIN, 0}, {fd, POLLIN, 0}};
  while (::poll(fds, 2, timeout_ms) == -1 && errno == EINTR) {
  }
  return fds[0].revents ? 0 : fds[1].revents;
}

bool ModbusServer::answer_one() {
  modbus_t* context = context_.get();
  const int length = modbus_receive(context, query_.data());
  if (length == -1) return false;
  if (length == 0) return true;  // RTU: addressed to another unit
  if (endpoint_.transport == ModbusEndpoint::Transport::kTcp) skip_rest_of_request(length);
  if (!in_the_map(query_[static_cast<std::size_t>(modbus_get_header_length(context))])) {
    // libmodbus answers more than the map lists (report server id with its own version
    // string); the map promises exception 1 for those. A broadcast gets no answer.
    if (endpoint_.transport == ModbusEndpoint::Transport::kRtu && query_[0] == MODBUS_BROADCAST_ADDRESS) return true;
    return modbus_reply_exception(context, query_.data(), MODBUS_EXCEPTION_ILLEGAL_FUNCTION) != -1;
  }
  refresh_({mapping_->tab_input_registers, static_cast<std::size_t>(mapping_->nb_input_registers)},
           {mapping_->tab_registers, static_cast<std::size_t>(mapping_->nb_registers)});
  std::array<std::uint16_t, MODBUS_MAX_WRITE_REGISTERS> values;
  if (const std::optional<Write> write =
          decode_write(query_.data() + modbus_get_header_length(context),
                       {mapping_->tab_registers, static_cast<std::size_t>(mapping_->nb_registers)}, values))
    written_(write->address, write->values);
  return modbus_reply(context, query_.data(), length, mapping_.get()) != -1;
}

void ModbusServer::skip_rest_of_request(int length) {
  const int whole = kMbapLengthBefore + ((query_[4] << 8) | query_[5]);  // all in the socket: check_request()
  if (length >= whole) return;
  [[maybe_unused]] const ssize_t skipped = ::recv(modbus_get_socket(context_.get()), query_.data() + length,
                                                  static_cast<std::size_t>(whole - length), MSG_DONTWAIT);
}

void ModbusServer::serve_tcp() {
  // Not listening yet (the port was taken at construction): try again with back-off until it
  // is free, or stop.
  Backoff relisten(kReopenFirst, kReopenMax);
  while (listen_fd_.get() == -1) {
    const auto delay = std::chrono::duration_cast<std::chrono::milliseconds>(relisten.failed());
    if (wait_readable(-1, static_cast<int>(delay.count())) == 0 && stopping_.load(std::memory_order_relaxed)) return;
    if (!listen()) continue;
    spdlog::info("modbus server {}: listening now", describe());
    healthy_.store(true, std::memory_order_relaxed);
  }
  std::vector<TcpClient> clients;
  clients.reserve(static_cast<std::size_t>(max_clients_));
  std::vector<pollfd> fds;
  bool evicting = false;       // log a full server once, not once per closed connection
  bool cannot_accept = false;  // and a process out of descriptors once
  const auto drop = [&](std::size_t i, const char* why) {
    spdlog::debug("modbus server {}: dropped a client ({})", describe(), why);
    clients.erase(clients.begin() + static_cast<std::ptrdiff_t>(i));
    evicting = false;
  };
  while (!stopping_.load(std::memory_order_relaxed)) {
    fds.assign({{wake_fd_.get(), POLLIN, 0}, {listen_fd_.get(), POLLIN, 0}});
    for (const TcpClient& client : clients) fds.push_back({client.fd.get(), POLLIN | POLLRDHUP, 0});
    if (::poll(fds.data(), fds.size(), poll_timeout_ms(clients, std::chrono::steady_clock::now())) == -1)
      continue;  // EINTR
    if (fds[0].revents) break;
    const auto now = std::chrono::steady_clock::now();
    // One request per readable client per round, so a flooding client cannot starve the others.
    for (std::size_t i = clients.size(); i-- > 0;) {
      TcpClient& client = clients[i];
      if (fds[i + 2].revents) {
        const Next next = check_request(client, fds[i + 2].revents, now);
        if (next == Next::kDrop) {
          drop(i, modbus_strerror(errno));
          continue;
        }
        if (next == Next::kAnswer) {
          client.last_request = now;
          modbus_set_socket(context_.get(), client.fd.get());
          const bool keep = answer_one();
          modbus_set_socket(context_.get(), -1);
          if (!keep) {
            drop(i, modbus_strerror(errno));
            continue;
          }
        }
      }
      if (client.incomplete_since && now - *client.incomplete_since >= std::chrono::milliseconds(kRequestTimeoutMs))
        drop(i, "a request still incomplete");
    }
    if (!(fds[1].revents & POLLIN)) continue;
    UniqueFd client(::accept4(listen_fd_.get(), nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK));
    if (client.get() == -1) {
      // Out of descriptors or memory: the connection stays queued and poll() would return at
      // once; wait a little (or for stop) instead of spinning a core.
      if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
        if (!std::exchange(cannot_accept, true))
          spdlog::warn("modbus server {}: cannot accept a connection: {}", describe(), std::strerror(errno));
        wait_readable(-1, kAcceptRetryMs);
      }
      continue;
    }
    cannot_accept = false;
    if (static_cast<int>(clients.size()) >= max_clients_) {
      // Refusing every newcomer would lock a rebooted PLC out for good: the connections its
      // earlier lives left half-open never send again. The quietest client goes instead, if it
      // has been quiet for kQuietBeforeClosingMs: a client that polls keeps its place, so that
      // a tool or a port scan connecting cannot take it, nor two clients take turns.
      const auto quietest = std::ranges::min_element(clients, {}, &TcpClient::last_request);
      const bool quiet = now - quietest->last_request >= std::chrono::milliseconds(kQuietBeforeClosingMs);
      if (!std::exchange(evicting, true))
        spdlog::warn(
            "modbus server {}: {} clients already; a new one takes the place of one quiet for {} s, or is "
            "refused",
            describe(), max_clients_, kQuietBeforeClosingMs / 1000);
      if (!quiet) continue;  // refused: closed by UniqueFd
      clients.erase(quietest);
    }
    set_client_options(client.get());
    clients.emplace_back(std::move(client), now);
  }
}

void ModbusServer::serve_rtu() {
  modbus_t* context = context_.get();
  Backoff reopen(kReopenFirst, kReopenMax);
  bool was_open = healthy_.load(std::memory_order_relaxed);  // not when the device was missing at construction
  while (!stopping_.load(std::memory_order_relaxed)) {
    if (!healthy_.load(std::memory_order_relaxed)) {
      const auto delay = std::chrono::duration_cast<std::chrono::milliseconds>(reopen.failed());
      if (wait_readable(-1, static_cast<int>(delay.count())) == 0 && stopping_.load(std::memory_order_relaxed)) break;
      if (!connect_context(context, endpoint_)) continue;
      spdlog::info("modbus server {}: serial line open{}", describe(), std::exchange(was_open, true) ? " again" : "");
      reopen.succeeded();
      healthy_.store(true, std::memory_order_relaxed);
    }
    const short events = wait_readable(modbus_get_socket(context), -1);
    if (events == 0) break;  // stop
    if (events & (POLLHUP | POLLERR | POLLNVAL)) {
      spdlog::error("modbus server {}: serial line failed; reopening with back-off up to {} ms", describe(),
                    kReopenMax.count());
      modbus_close(context);
      healthy_.store(false, std::memory_order_relaxed);
      continue;
    }
    // A frame with a bad CRC or one cut short: discard what is left of it and listen on.
    if (!answer_one()) modbus_flush(context);
  }
}

}  // namespace lipdrive
