// [osc_control] (docs/osc.md): the remote commands a capture operator sends over OSC, as Live
// Link Face takes them: /RecordStart s i (slate, take), /RecordStop, /Slate s, /Take i; and
// /lipdrive/calibrate, /lipdrive/output_enable i. They act through DriveControl, like the
// Modbus control registers and the GPIO buttons.
//
// Thread model: one thread of its own receives and handles the messages (drivers/
// osc_receiver.hpp); it writes DriveControl's atomics and, under a mutex, the slate and take
// the main thread reads when it starts a take. The Daemon declares it after the pipeline
// whose DriveControl it writes, so it is joined first.
#pragma once

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
  /// Binds address:port. Throws UdpError naming the address ("Address already in use").
  OscControl(const std::string& address, int port, DriveControl& control);
  ~OscControl();
  OscControl(const OscControl&) = delete;
  OscControl& operator=(const OscControl&) = delete;

  /// Main thread, when a take starts: "<slate>_<take>" once a slate was given, then counts the
  /// take up, as Live Link Face does; nullopt without a slate.
  std::optional<std::string> next_take_name();

  std::string describe() const { return "osc control " + receiver_.describe(); }
  int port() const { return receiver_.port(); }

 private:
  void run();
  void handle(const OscMessage& message);

  OscReceiver receiver_;  // the thread's
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
