#include "drivers/ola_client.hpp"

#include <ola/DmxBuffer.h>
#include <ola/Logging.h>
#include <ola/client/StreamingClient.h>

#include <mutex>

namespace lipdrive {
namespace {

// libola logs to nowhere until told otherwise; its warnings (a closed socket) are what
// send() already reports, so keep them quiet rather than on stderr.
void quiet_libola_logging() {
  static std::once_flag once;
  std::call_once(once, [] { ola::InitLogging(ola::OLA_LOG_NONE, ola::OLA_LOG_NULL); });
}

}  // namespace

OlaDmxClient::OlaDmxClient(int rpc_port) : rpc_port_(rpc_port), buffer_(std::make_unique<ola::DmxBuffer>()) {
  quiet_libola_logging();
}

OlaDmxClient::~OlaDmxClient() { disconnect(); }

bool OlaDmxClient::connect() {
  disconnect();
  ola::client::StreamingClient::Options options;
  options.auto_start = false;  // olad is a service of its own, never a child of lipdrive
  options.server_port = static_cast<std::uint16_t>(rpc_port_);
  auto client = std::make_unique<ola::client::StreamingClient>(options);
  if (!client->Setup()) {
    last_error_ = "cannot connect to " + describe() + " (is olad running?)";
    return false;
  }
  client_ = std::move(client);
  return true;
}

void OlaDmxClient::disconnect() {
  if (client_) client_->Stop();
  client_.reset();
}

bool OlaDmxClient::send(unsigned universe, std::span<const std::uint8_t> slots, std::uint8_t priority) {
  if (!client_) {
    last_error_ = "not connected to " + describe();
    return false;
  }
  buffer_->Set(slots.data(), static_cast<unsigned>(slots.size()));
  ola::client::StreamingClient::SendArgs args;
  args.priority = priority;
  if (client_->SendDMX(universe, *buffer_, args)) return true;
  last_error_ = describe() + " closed the connection";
  disconnect();
  return false;
}

std::string OlaDmxClient::describe() const { return "olad 127.0.0.1:" + std::to_string(rpc_port_); }

}  // namespace lipdrive
