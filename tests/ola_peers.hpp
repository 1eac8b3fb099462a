// Test-side OLA peers: an olad started by the test (as an unprivileged user when the test
// runs as root, with its own configuration folder and RPC port so that tests running in
// parallel never meet), and readers of what olad holds for a universe (libola's OlaClient).
#pragma once

#include "serial_peers.hpp"

#include <fcntl.h>
#include <grp.h>
#include <netinet/in.h>
#include <ola/DmxBuffer.h>
#include <ola/Logging.h>
#include <ola/client/OlaClient.h>
#include <ola/io/SelectServer.h>
#include <ola/network/IPV4Address.h>
#include <ola/network/SocketAddress.h>
#include <ola/network/TCPSocket.h>
#include <pwd.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace lipdrive::test {

inline bool program_exists(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  for (std::size_t start = 0; start <= dirs.size();) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    if (::access((dirs.substr(start, end - start) + "/" + name).c_str(), X_OK) == 0) return true;
    start = end + 1;
  }
  return false;
}

/// olad with every plugin disabled (the universes live in olad itself; nothing goes on the
/// network), no web server and its own RPC port. olad refuses to run as root: as root the
/// test starts it as `nobody` through setpriv, in a configuration folder `nobody` owns.
class OladProcess {
 public:
  static bool installed() { return program_exists("olad"); }

  explicit OladProcess(int rpc_port) : rpc_port_(rpc_port) {
    std::string pattern = (std::filesystem::temp_directory_path() / "lipdrive-olad-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    dir_ = pattern;
    for (const char* plugin :
         {"artnet",  "dummy",    "e131",       "espnet",           "ftdidmx", "gpio",      "karate",   "kinet",
          "milinst", "nanoleaf", "opendmx",    "openpixelcontrol", "osc",     "pathport",  "renard",   "sandnet",
          "shownet", "spi",      "stageprofi", "uartdmx",          "usbdmx",  "usbserial", "dmx4linux"})
      std::ofstream(dir_ / (std::string("ola-") + plugin + ".conf")) << "enabled = false\n";
    if (::geteuid() == 0) {
      const passwd* nobody = ::getpwnam("nobody");
      if (!nobody) throw std::runtime_error("no user nobody to run olad as");
      uid_ = nobody->pw_uid;
      gid_ = nobody->pw_gid;
      for (const auto& entry : std::filesystem::directory_iterator(dir_))
        if (::chown(entry.path().c_str(), uid_, gid_) != 0) throw std::runtime_error("chown failed");
      if (::chown(dir_.c_str(), uid_, gid_) != 0) throw std::runtime_error("chown failed");
    }
    start();
  }
  ~OladProcess() {
    stop();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  OladProcess(const OladProcess&) = delete;
  OladProcess& operator=(const OladProcess&) = delete;

  /// Starts olad and waits until its RPC port accepts connections.
  void start() {
    const std::string port = std::to_string(rpc_port_), log = (dir_ / "olad.log").string();
    std::vector<std::string> args;
    if (::geteuid() == 0)
      args = {"setpriv", "--reuid=" + std::to_string(uid_), "--regid=" + std::to_string(gid_), "--clear-groups"};
    for (const std::string& arg :
         {std::string("olad"), std::string("--config-dir"), dir_.string(), std::string("--rpc-port"), port,
          std::string("--no-http"), std::string("--no-register-with-dns-sd"), std::string("--log-level"),
          std::string("2")})
      args.push_back(arg);
    std::vector<char*> argv;
    for (auto& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int error = posix_spawnp(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (error != 0) throw std::runtime_error("cannot start olad");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!accepts()) {
      if (std::chrono::steady_clock::now() > deadline) throw std::runtime_error("olad does not listen on " + port);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  /// SIGKILL: olad vanishes without closing anything cleanly.
  void kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  /// SIGSTOP / SIGCONT: olad hangs (still accepting connections, reading nothing) and wakes.
  void pause() const {
    if (pid_ > 0) ::kill(pid_, SIGSTOP);
  }
  void resume() const {
    if (pid_ > 0) ::kill(pid_, SIGCONT);
  }
  void stop() {
    if (pid_ <= 0) return;
    resume();  // a stopped process holds its SIGTERM until it runs again
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  int rpc_port() const { return rpc_port_; }

 private:
  bool accepts() const {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(static_cast<std::uint16_t>(rpc_port_));
    const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
    ::close(fd);
    return ok;
  }

  int rpc_port_;
  std::filesystem::path dir_;
  uid_t uid_ = 0;
  gid_t gid_ = 0;
  pid_t pid_ = -1;
};

using Universe = std::vector<std::uint8_t>;

namespace detail {

inline void on_fetched(std::optional<Universe>* out, ola::io::SelectServer* ss, const ola::client::Result& result,
                       const ola::client::DMXMetadata&, const ola::DmxBuffer& data) {
  if (result.Success()) *out = Universe(data.GetRaw(), data.GetRaw() + data.Size());
  ss->Terminate();
}

}  // namespace detail

/// What olad holds for `universe` now (FetchDMX); nullopt when olad does not answer.
inline std::optional<Universe> fetch_universe(int rpc_port, unsigned universe) {
  ola::InitLogging(ola::OLA_LOG_NONE, ola::OLA_LOG_NULL);
  std::unique_ptr<ola::network::TCPSocket> socket(ola::network::TCPSocket::Connect(
      ola::network::IPV4SocketAddress(ola::network::IPV4Address::Loopback(), static_cast<std::uint16_t>(rpc_port))));
  if (!socket) return std::nullopt;
  ola::io::SelectServer ss;
  ola::client::OlaClient client(socket.get());
  if (!client.Setup()) return std::nullopt;
  ss.AddReadDescriptor(socket.get());
  std::optional<Universe> out;
  client.FetchDMX(universe, ola::NewSingleCallback(&detail::on_fetched, &out, &ss));
  ss.RegisterSingleTimeout(2000, ola::NewSingleCallback(&ss, &ola::io::SelectServer::Terminate));
  ss.Run();
  ss.RemoveReadDescriptor(socket.get());
  client.Stop();
  return out;
}

/// Every frame olad passes on for one universe, with the time it arrived (a client
/// registered for the universe, on a thread of its own).
class UniverseWatcher {
 public:
  struct Update {
    std::chrono::steady_clock::time_point time;
    Universe slots;
  };

  UniverseWatcher(int rpc_port, unsigned universe) {
    ola::InitLogging(ola::OLA_LOG_NONE, ola::OLA_LOG_NULL);
    socket_.reset(ola::network::TCPSocket::Connect(
        ola::network::IPV4SocketAddress(ola::network::IPV4Address::Loopback(), static_cast<std::uint16_t>(rpc_port))));
    if (!socket_) throw std::runtime_error("UniverseWatcher: olad does not answer");
    client_ = std::make_unique<ola::client::OlaClient>(socket_.get());
    if (!client_->Setup()) throw std::runtime_error("UniverseWatcher: OlaClient setup failed");
    ss_.AddReadDescriptor(socket_.get());
    close_handler_ = ola::NewSingleCallback(this, &UniverseWatcher::closed);
    client_->SetCloseHandler(close_handler_);
    client_->SetDMXCallback(ola::NewCallback(this, &UniverseWatcher::received));
    client_->RegisterUniverse(universe, ola::client::REGISTER, ola::NewSingleCallback(&UniverseWatcher::registered));
    thread_ = std::thread([this] { ss_.Run(); });
  }
  ~UniverseWatcher() {
    ss_.Terminate();
    thread_.join();
    ss_.RemoveReadDescriptor(socket_.get());
    client_->Stop();
    client_.reset();
    // A single-use callback deletes itself when it runs; the client never deletes one that
    // did not run (olad still up), so it is ours then (LeakSanitizer found it).
    if (!closed_) delete close_handler_;
  }
  UniverseWatcher(const UniverseWatcher&) = delete;
  UniverseWatcher& operator=(const UniverseWatcher&) = delete;

  std::vector<Update> updates() const {
    std::lock_guard lock(mutex_);
    return updates_;
  }

 private:
  static void registered(const ola::client::Result&) {}
  void closed() {
    closed_ = true;
    ss_.Terminate();
  }
  void received(const ola::client::DMXMetadata&, const ola::DmxBuffer& data) {
    std::lock_guard lock(mutex_);
    updates_.push_back({std::chrono::steady_clock::now(), Universe(data.GetRaw(), data.GetRaw() + data.Size())});
  }

  std::unique_ptr<ola::network::TCPSocket> socket_;
  std::unique_ptr<ola::client::OlaClient> client_;
  ola::SingleUseCallback0<void>* close_handler_ = nullptr;  // the client's until it runs
  std::atomic<bool> closed_{false};                         // it ran
  ola::io::SelectServer ss_;
  mutable std::mutex mutex_;
  std::vector<Update> updates_;
  std::thread thread_;
};

}  // namespace lipdrive::test
