// [osc_control] (docs/osc.md): the remote commands a capture operator sends over OSC, as Live
// Link Face takes them: /RecordStart s i (slate, take), /RecordStop, /Slate s, /Take i; and
// /lipdrive/calibrate, /lipdrive/output_enable i. They act through DriveControl, like the
// Modbus control registers and the GPIO buttons.
//
// Thread model: one thread of its own receives and handles the messages (drivers/
// osc_receiver.hpp); it writes DriveControl's atomics and, under a mutex, the slate and take
// the main thread reads when it starts a take. A port it cannot bind (another program holds
// it, the address is not up yet) is tried again by that thread with the one back-off. The Daemon declares it after the
// pipeline whose DriveControl it writes, so it is joined first.
#pragma once

#include "core/backoff.hpp"
#include "drivers/osc_receiver.hpp"
#include "firmware_app/daemon/log_throttle.hpp"
#include "firmware_app/outputs/output.hpp"

#include <array>
#include <atomic>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace lipdrive {

class OscControl {
 public:
  /// Binds address:port, a resolved one (Config). When the bind fails ("Address already in
  /// use"), says so and keeps trying on its thread: the daemon runs on without OSC control until
  /// then, as without the monitor. Throws UdpError only for an address that does not resolve.
  OscControl(const std::string& address, int port, DriveControl& control);
  ~OscControl();
  OscControl(const OscControl&) = delete;
  OscControl& operator=(const OscControl&) = delete;

  /// Main thread, when a take starts: "<slate>_<take>" once a slate was given, then counts the
  /// take up, as Live Link Face does; nullopt without a slate.
  std::optional<std::string> next_take_name();

  std::string describe() const { return "osc control udp " + where_; }
  /// The port bound (port 0 picks a free one); 0 while not bound.
  int port() const { return bound_port_.load(std::memory_order_relaxed); }

 private:
  void run();
  /// Binds the receiver; false, having logged why when it is the first failure in a row.
  bool bind();
  void handle(const OscMessage& message);

  const std::string address_;
  const int port_;
  const std::string where_;              // "127.0.0.1:8000"
  std::optional<OscReceiver> receiver_;  // the thread's (the constructor's before it starts)
  Backoff rebind_;                       // the thread's
  std::atomic<int> bound_port_{0};
  DriveControl& control_;
  // A command's lines at most ten a second each (a fader that sends output_enable at its own
  // rate, a sender gone wrong), with the count held back; refused datagrams, bundles and
  // commands too.
  std::array<LogThrottle, 6> command_log_;  // the thread's, by command
  LogThrottle refused_log_;                 // the thread's
  std::mutex mutex_;
  std::string slate_;  // under mutex_
  int take_ = 1;       // under mutex_
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace lipdrive
