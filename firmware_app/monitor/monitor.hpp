// The operator's monitor page (docs/monitor.md), served by the daemon over HTTP (cpp-httplib):
//
//   GET  /                      the page (embedded in the binary)
//   GET  /api/state             the drive's state as JSON (counters, latency, channels, outputs)
//   GET  /api/history?since=N   the drive channels over the last 10 s, sampled 25 times a second
//   GET  /preview.jpg           the newest preview with its overlay
//   GET  /preview-side.jpg      the side camera's, with its profile (404 without a side camera)
//   POST /api/calibrate, /api/record/start|stop, /api/output/enable|disable
//                               commands; they need the control token (401 without, 403 wrong)
//
// Threads, all the monitor's own, none on the frame path: the listener accepts connections;
// a fixed pool of workers answers them, one request per connection (when every worker is busy
// and as many connections wait, the listener answers 503 itself); the encoder takes previews
// from the PreviewFeed and, while someone fetches them, draws the overlay and encodes the JPEG;
// it also samples the drive channels for the history. What they read of the pipeline they read lock-free (its seqlocks and
// atomics); commands go through DriveControl's atomics like every other control input.
//
// Lifetime: the Daemon owns it and declares it after everything it reads (pipeline, outputs,
// feed, drive control), so it is destroyed, its threads joined, before any of them.
#pragma once

#include "core/drive_channels.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/daemon/log_throttle.hpp"
#include "firmware_app/daemon/pipeline.hpp"
#include "firmware_app/daemon/preview_feed.hpp"
#include "firmware_app/outputs/output.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace httplib {
class Server;
}

namespace lipdrive {

/// What the page shows and commands; everything referenced is the Daemon's and outlives the
/// Monitor.
struct MonitorSources {
  const Pipeline& pipeline;
  DriveControl& control;
  PreviewFeed& preview;
  std::vector<const Output*> outputs;
  std::vector<ChannelSpec> channels;
  std::string performer;  // "" = uncalibrated defaults
  bool model_mismatch = false;
};

/// A new random control token: 32 hexadecimal digits from the kernel's random source.
std::string new_control_token();

class Monitor {
 public:
  /// `token`: what the commands must carry (Authorization: Bearer <token>); never empty.
  Monitor(Config::Monitor settings, MonitorSources sources, std::string token);
  ~Monitor();
  Monitor(const Monitor&) = delete;
  Monitor& operator=(const Monitor&) = delete;

  /// Listens and starts the threads. False, logged with the address, the port and why, when
  /// the address cannot be listened on; the daemon then runs on without the page.
  bool start();
  /// Stops listening, finishes the requests in hand, joins every thread.
  void stop();

  /// "http://<address>:<port>/".
  std::string url() const;

 private:
  struct History;
  struct Counters {
    std::atomic<std::uint64_t> requests{0}, turned_away{0}, refused{0}, commands{0}, encoded{0};
  };
  /// A preview encoded by the encoder thread for the workers to send.
  struct Jpeg {
    std::mutex mutex;
    std::condition_variable published;
    std::shared_ptr<const std::string> bytes;  // none before the first
    std::uint64_t sequence = 0;                // the front frame's
    std::int64_t encoded_ns = 0;               // when it was encoded
    void publish(std::string jpeg, std::uint64_t frame_sequence, std::int64_t now_ns);
  };

  void add_routes();
  void encoder_loop();
  void sample_channels();
  /// The state's JSON, shared by every request until it is rebuilt (at most every kStateMaxAge).
  std::shared_ptr<const std::string> state_json();
  std::string history_json(std::uint64_t since) const;
  /// The request's token against ours: 0 when it carries the right one, else 401 or 403.
  int authorise(const std::string& authorization_header);

  const Config::Monitor settings_;
  MonitorSources sources_;
  const std::string token_;
  const std::int64_t start_ns_;
  Counters counters_;
  LogThrottle refused_log_;  // refused commands' lines at most ten a second (workers)

  std::unique_ptr<History> history_;  // encoder writes, workers read; under history_mutex_
  mutable std::mutex history_mutex_;

  Jpeg front_jpeg_, side_jpeg_;  // the newest preview's images
  // When a preview was last asked for: the encoder works only while someone looks.
  std::atomic<std::int64_t> preview_asked_ns_;

  std::mutex state_mutex_;  // the state, rebuilt at most every kStateMaxAge for any number of clients
  std::shared_ptr<const std::string> state_;
  std::int64_t state_time_ns_ = 0;

  std::unique_ptr<httplib::Server> server_;
  std::atomic<std::thread::id> listener_id_{};  // requests on this thread are the turned-away ones
  std::atomic<bool> stop_{false};
  std::thread listener_, encoder_;  // last: they use everything above
};

}  // namespace lipdrive
