#include "firmware_app/monitor/monitor.hpp"

#include "drivers/clock.hpp"
#include "drivers/thread_scheduling.hpp"
#include "firmware_app/daemon/status_word.hpp"
#include "firmware_app/monitor/monitor_page.hpp"
#include "firmware_app/monitor/preview_image.hpp"

#include <fmt/format.h>
#include <httplib.h>
#include <netdb.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <functional>
#include <random>
#include <string_view>
#include <utility>

namespace lipdrive {
namespace {

constexpr std::int64_t kSamplePeriodNs = 40'000'000;  // the history: 25 samples a second
constexpr int kHistorySamples = 256;                  // 10.24 s of them
constexpr std::int64_t kStateMaxAgeNs = 50'000'000;   // state rebuilt at most 20 times a second
constexpr int kJpegQuality = 75;
// Previews are drawn and encoded while one was asked for within this time; the first request
// after a pause waits at most kFreshPreviewWaitNs for a fresh one.
constexpr std::int64_t kPreviewInterestNs = 2'000'000'000;
constexpr std::chrono::milliseconds kFreshPreviewWait(1000);
// A client that stalls holds a worker at most this long per read or write; stop() waits for
// the reads in hand.
constexpr time_t kIoTimeoutS = 1;

/// The connection workers: a fixed number of threads and as many connections waiting for one.
/// A connection beyond those runs on the listener thread, where the monitor answers 503 at
/// once (Monitor::add_routes).
class WorkerPool final : public httplib::TaskQueue {
 public:
  explicit WorkerPool(int workers) : capacity_(static_cast<std::size_t>(workers)) {
    for (int i = 0; i < workers; ++i) name_thread(threads_.emplace_back([this] { work(); }), "lipdrive-httpw");
  }

  void enqueue(std::function<void()> connection) override {
    {
      std::lock_guard lock(mutex_);
      if (waiting_.size() < capacity_) {
        waiting_.push_back(std::move(connection));
        ready_.notify_one();
        return;
      }
    }
    connection();  // turned away, on the listener thread
  }

  /// Serves what waits, then joins the workers.
  void shutdown() override {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
    }
    ready_.notify_all();
    for (std::thread& thread : threads_) thread.join();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> connection;
      {
        std::unique_lock lock(mutex_);
        ready_.wait(lock, [this] { return stopping_ || !waiting_.empty(); });
        if (waiting_.empty()) return;
        connection = std::move(waiting_.front());
        waiting_.pop_front();
      }
      connection();
    }
  }

  const std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> waiting_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

/// Answers with `bytes` as they are. A body set with set_content httplib copies, and a text or
/// JSON one it compresses again for every request whose client accepts it (Brotli for a browser
/// or an httplib client: a quarter of the workers' CPU time with 50 clients polling the state); a
/// body of known length from a provider goes out uncompressed, straight from `bytes`, which
/// `owner` keeps alive until it is sent.
void send_as_is(httplib::Response& response, std::string_view bytes, const char* content_type,
                std::shared_ptr<const void> owner = nullptr) {
  response.set_content_provider(
      bytes.size(), content_type,
      [bytes, owner = std::move(owner)](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
        return sink.write(bytes.data() + offset, length);
      });
}

void send_as_is(httplib::Response& response, std::shared_ptr<const std::string> bytes, const char* content_type) {
  const std::string_view view = *bytes;
  send_as_is(response, view, content_type, std::move(bytes));
}

/// Compares in time independent of where the strings differ.
bool same_token(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  unsigned char difference = 0;
  for (std::size_t i = 0; i < a.size(); ++i) difference |= static_cast<unsigned char>(a[i] ^ b[i]);
  return difference == 0;
}

double seconds(std::int64_t ns) { return static_cast<double>(ns) / 1e9; }

}  // namespace

struct Monitor::History {
  std::uint64_t next = 0;  // samples taken so far; sample i is at i % kHistorySamples
  std::array<double, kHistorySamples> time_s{};
  std::array<std::uint16_t, kHistorySamples> status{};
  std::array<std::array<float, kMaxChannels>, kHistorySamples> values{};
};

std::string new_control_token() {
  std::random_device random;  // getrandom(2)
  std::string token;
  for (int i = 0; i < 4; ++i) token += fmt::format("{:08x}", random());
  return token;
}

Monitor::Monitor(Config::Monitor settings, MonitorSources sources, std::string token)
    : settings_(std::move(settings)),
      sources_(std::move(sources)),
      token_(std::move(token)),
      start_ns_(monotonic_ns()),
      history_(std::make_unique<History>()),
      preview_asked_ns_(start_ns_ - kPreviewInterestNs - 1),  // nobody yet
      server_(std::make_unique<httplib::Server>()) {
  const int workers = settings_.max_clients;
  server_->new_task_queue = [workers] { return new WorkerPool(workers); };
  // SO_REUSEADDR only: a restart may bind at once, but a port another process holds stays taken
  // (httplib's default adds SO_REUSEPORT, which would let two daemons share it).
  server_->set_socket_options([](socket_t socket) {
    const int yes = 1;
    ::setsockopt(socket, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  server_->set_keep_alive_max_count(1);  // one request per connection: a worker is never held idle
  server_->set_keep_alive_timeout(kIoTimeoutS);  // nor for longer than a read waits for its request
  server_->set_read_timeout(kIoTimeoutS, 0);
  server_->set_write_timeout(kIoTimeoutS, 0);
  server_->set_payload_max_length(1024);  // commands carry no body
  add_routes();
}

Monitor::~Monitor() { stop(); }

std::string Monitor::url() const {
  const bool ipv6 = settings_.address.find(':') != std::string::npos;
  return ipv6 ? fmt::format("http://[{}]:{}/", settings_.address, settings_.port)
              : fmt::format("http://{}:{}/", settings_.address, settings_.port);
}

bool Monitor::start() {
  const auto fail = [this](std::string_view why) {
    spdlog::error("monitor: cannot listen on {}:{}: {}; the daemon runs on without the monitor page", settings_.address,
                  settings_.port, why);
    return false;
  };
  // The address first, for a message that says what is wrong with it.
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  const std::string port = std::to_string(settings_.port);
  if (const int error = ::getaddrinfo(settings_.address.c_str(), port.c_str(), &hints, &found); error != 0)
    return fail(fmt::format("the address does not resolve ({})", ::gai_strerror(error)));
  ::freeaddrinfo(found);
  errno = 0;
  if (!server_->bind_to_port(settings_.address, settings_.port)) {
    const int error = errno;
    return fail(error != 0 ? std::strerror(error) : "bind failed");
  }
  listener_ = std::thread([this] {
    listener_id_ = std::this_thread::get_id();
    server_->listen_after_bind();
  });
  name_thread(listener_, "lipdrive-http");
  // Listening, before anything may call stop(): httplib's stop() only closes a running server.
  for (int waited_ms = 0; !server_->is_running() && waited_ms < 5000; ++waited_ms)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  encoder_ = std::thread(&Monitor::encoder_loop, this);
  name_thread(encoder_, "lipdrive-preview");
  spdlog::info("monitor: {} ({} connections served at once, previews {} a second)", url(), settings_.max_clients,
               settings_.preview_fps);
  return true;
}

void Monitor::stop() {
  stop_ = true;
  for (Jpeg* jpeg : {&front_jpeg_, &side_jpeg_}) {
    std::lock_guard lock(jpeg->mutex);  // a worker waiting for a preview sees stop_ before it sleeps again
    jpeg->published.notify_all();
  }
  server_->stop();
  if (listener_.joinable()) listener_.join();
  if (encoder_.joinable()) encoder_.join();
  refused_log_.log_held_back("monitor: refused commands");
}

int Monitor::authorise(const std::string& authorization) {
  constexpr std::string_view kBearer = "Bearer ";
  if (!authorization.starts_with(kBearer)) return 401;
  return same_token(std::string_view(authorization).substr(kBearer.size()), token_) ? 0 : 403;
}

void Monitor::add_routes() {
  using httplib::Request, httplib::Response;
  server_->set_pre_routing_handler([this](const Request& request, Response& response) {
    counters_.requests.fetch_add(1, std::memory_order_relaxed);
    // The commands take no body. A chunked one has no length for the payload limit to refuse it
    // by, and httplib would read all of it before any handler (the token's check) runs.
    if (request.has_header("Transfer-Encoding")) {
      response.status = 413;
      response.set_header("Connection", "close");
      response.set_content("the monitor takes no request body\n", "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    }
    // A command sent without a length (`curl -X POST` without `-d`): httplib would wait for a
    // body until the client closed, and answer 400 with nothing said a second later, holding a
    // worker. The commands take none: say how to send one.
    if (request.method == "POST" && !request.has_header("Content-Length")) {
      response.status = 411;
      response.set_content("send the command with Content-Length: 0 (curl -d '')\n", "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    }
    // Byte ranges: httplib would answer a request for the same range many times over with a
    // part for each (a 5.6 KB request got 28 MB), and nothing on the page asks for one.
    if (request.has_header("Range")) {
      response.status = 416;
      response.set_content("the monitor serves whole responses only\n", "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (std::this_thread::get_id() != listener_id_.load()) return httplib::Server::HandlerResponse::Unhandled;
    counters_.turned_away.fetch_add(1, std::memory_order_relaxed);
    response.status = 503;
    response.set_header("Retry-After", "1");
    response.set_content("the monitor is serving as many clients as it may; try again\n", "text/plain");
    return httplib::Server::HandlerResponse::Handled;
  });
  server_->Get("/", [](const Request&, Response& response) {
    response.set_header("Cache-Control", "no-store");
    send_as_is(response, kMonitorPage, "text/html; charset=utf-8");
  });
  server_->Get("/api/state", [this](const Request&, Response& response) {
    response.set_header("Cache-Control", "no-store");
    send_as_is(response, state_json(), "application/json");
  });
  server_->Get("/api/history", [this](const Request& request, Response& response) {
    std::uint64_t since = 0;
    if (request.has_param("since")) {
      try {
        since = std::stoull(request.get_param_value("since"));
      } catch (const std::exception&) {
        response.status = 400;
        response.set_content("since: a sample number\n", "text/plain");
        return;
      }
    }
    response.set_header("Cache-Control", "no-store");
    send_as_is(response, std::make_shared<const std::string>(history_json(since)), "application/json");
  });
  const auto serve = [this](Jpeg& jpeg) {
    return [this, &jpeg](const Request&, Response& response) {
      const std::int64_t asked_ns = monotonic_ns();
      preview_asked_ns_.store(asked_ns, std::memory_order_relaxed);
      std::shared_ptr<const std::string> bytes;
      std::uint64_t sequence = 0;
      {
        std::unique_lock lock(jpeg.mutex);
        // Nobody looked for a while, so the encoder rested: wait for the preview it now makes.
        if (asked_ns - jpeg.encoded_ns > kPreviewInterestNs)
          jpeg.published.wait_for(lock, kFreshPreviewWait, [&] { return jpeg.encoded_ns >= asked_ns || stop_.load(); });
        bytes = jpeg.bytes;
        sequence = jpeg.sequence;
      }
      response.set_header("Cache-Control", "no-store");
      if (!bytes) {
        response.status = 503;
        response.set_header("Retry-After", "1");
        response.set_content("no frame yet\n", "text/plain");
        return;
      }
      response.set_header("X-Frame-Sequence", std::to_string(sequence));
      send_as_is(response, std::move(bytes), "image/jpeg");
    };
  };
  server_->Get("/preview.jpg", serve(front_jpeg_));
  if (sources_.pipeline.side_camera()) server_->Get("/preview-side.jpg", serve(side_jpeg_));

  // Commands: the token, then one atomic write to the drive control, as a Modbus register does.
  const auto command = [this](std::string what, std::function<void()> act) {
    return [this, what = std::move(what), act = std::move(act)](const Request& request, Response& response) {
      if (const int refusal = authorise(request.get_header_value("Authorization")); refusal != 0) {
        counters_.refused.fetch_add(1, std::memory_order_relaxed);
        response.status = refusal;
        if (refusal == 401) response.set_header("WWW-Authenticate", "Bearer realm=\"lipdrive\"");
        response.set_content(refusal == 401 ? "this needs the control token\n" : "wrong control token\n", "text/plain");
        if (std::uint64_t held = 0; refused_log_.pass(held))
          spdlog::warn("monitor: {} refused ({}) from {}{}", what, refusal, request.remote_addr, held_back_note(held));
        return;
      }
      act();
      counters_.commands.fetch_add(1, std::memory_order_relaxed);
      spdlog::info("monitor: {} from {}", what, request.remote_addr);
      response.set_content("{\"ok\":true}\n", "application/json");
    };
  };
  DriveControl& control = sources_.control;
  server_->Post("/api/calibrate", command("calibrate", [&control] { control.calibrate_requests.fetch_add(1); }));
  server_->Post("/api/record/start", command("record start", [&control] { control.recording_request.store(1); }));
  server_->Post("/api/record/stop", command("record stop", [&control] { control.recording_request.store(0); }));
  server_->Post("/api/output/enable", command("output enable", [&control] { control.outputs_enabled.store(true); }));
  server_->Post("/api/output/disable", command("output disable", [&control] { control.outputs_enabled.store(false); }));
}

// ---------------------------------------------------------------- encoder thread

void Monitor::Jpeg::publish(std::string jpeg, std::uint64_t frame_sequence, std::int64_t now_ns) {
  auto shared = std::make_shared<const std::string>(std::move(jpeg));
  {
    std::lock_guard lock(mutex);
    bytes = std::move(shared);
    sequence = frame_sequence;
    encoded_ns = now_ns;
  }
  published.notify_all();
}

void Monitor::encoder_loop() {
  cv::Mat canvas;
  JpegEncoder front(kJpegQuality), side(kJpegQuality);  // each keeps its FFmpeg encoder for its image size
  std::int64_t next_sample_ns = monotonic_ns();
  bool encoding_failed = false;  // logged once until a picture is encoded again
  while (!stop_.load(std::memory_order_relaxed)) {
    const std::int64_t wait_ns = std::max<std::int64_t>(next_sample_ns - monotonic_ns(), 0);
    const PreviewFrame* frame = sources_.preview.take(std::chrono::nanoseconds(wait_ns));
    // Taken either way, so that the next one is the newest; drawn and encoded only for a viewer.
    if (frame && monotonic_ns() - preview_asked_ns_.load(std::memory_order_relaxed) <= kPreviewInterestNs) {
      // A picture that cannot be encoded (FFmpeg refusing a size, memory) costs the page its
      // preview, never the daemon its life: an exception out of this thread would end the process.
      try {
        front_jpeg_.publish(preview_jpeg(*frame, canvas, front), frame->sequence, monotonic_ns());
        if (frame->side) side_jpeg_.publish(side_preview_jpeg(*frame, canvas, side), frame->sequence, monotonic_ns());
        counters_.encoded.fetch_add(1, std::memory_order_relaxed);
        encoding_failed = false;
      } catch (const std::exception& e) {
        if (!std::exchange(encoding_failed, true))
          spdlog::warn("monitor: the preview cannot be encoded: {}; the page shows the last one meanwhile", e.what());
      }
    }
    const std::int64_t now = monotonic_ns();
    if (now < next_sample_ns) continue;
    sample_channels();
    next_sample_ns += kSamplePeriodNs;
    if (next_sample_ns <= now) next_sample_ns = now + kSamplePeriodNs;  // after a stall: no burst
  }
}

void Monitor::sample_channels() {
  DriveFrame drive;
  sources_.pipeline.latest_drive(drive);
  const double time_s = seconds(monotonic_ns() - start_ns_);
  std::lock_guard lock(history_mutex_);
  History& h = *history_;
  const std::size_t slot = h.next % kHistorySamples;
  h.time_s[slot] = time_s;
  h.status[slot] = drive.status;
  for (int i = 0; i < kMaxChannels; ++i)
    h.values[slot][static_cast<std::size_t>(i)] = static_cast<float>(drive.values[static_cast<std::size_t>(i)]);
  ++h.next;
}

// ---------------------------------------------------------------- JSON

std::string Monitor::history_json(std::uint64_t since) const {
  std::lock_guard lock(history_mutex_);
  const History& h = *history_;
  const std::uint64_t first = std::max(since, h.next > kHistorySamples ? h.next - kHistorySamples : 0);
  nlohmann::json time = nlohmann::json::array(), tracking = nlohmann::json::array(), values = nlohmann::json::array();
  for (std::size_t c = 0; c < sources_.channels.size(); ++c) values.push_back(nlohmann::json::array());
  for (std::uint64_t i = first; i < h.next; ++i) {
    const std::size_t slot = i % kHistorySamples;
    time.push_back(h.time_s[slot]);
    tracking.push_back((h.status[slot] & kStatusTracking) != 0);
    for (std::size_t c = 0; c < sources_.channels.size(); ++c) values[c].push_back(h.values[slot][c]);
  }
  return nlohmann::json{{"next", h.next},
                        {"period_ms", kSamplePeriodNs / 1'000'000},
                        {"time_s", std::move(time)},
                        {"tracking", std::move(tracking)},
                        {"values", std::move(values)}}
      .dump();
}

std::shared_ptr<const std::string> Monitor::state_json() {
  const std::int64_t now = monotonic_ns();
  std::lock_guard lock(state_mutex_);
  if (state_ && now - state_time_ns_ < kStateMaxAgeNs) return state_;
  const Pipeline& pipeline = sources_.pipeline;
  const SideCamera* side = pipeline.side_camera();
  const PipelineStats s = pipeline.stats();
  DriveFrame drive;
  pipeline.latest_drive(drive);
  FrameResult result;
  pipeline.latest(result);
  PerformerProfile recentred;
  const std::uint32_t calibrations = pipeline.recentred_profile(recentred);
  const auto bit = [&drive](StatusBit b) { return (drive.status & b) != 0; };

  nlohmann::json channels = nlohmann::json::array();
  for (std::size_t i = 0; i < sources_.channels.size(); ++i) {
    const ChannelSpec& c = sources_.channels[i];
    channels.push_back({{"name", c.name},
                        {"value", drive.values[i]},
                        {"min", std::min(c.out_min, c.out_max)},
                        {"max", std::max(c.out_min, c.out_max)},
                        {"neutral", c.neutral}});
  }
  nlohmann::json outputs = nlohmann::json::array();
  for (const Output* output : sources_.outputs)
    outputs.push_back({{"name", output->describe()}, {"healthy", output->healthy()}});
  const bool tracked = result.tracked && bit(kStatusTracking);
  nlohmann::json state = {
      {"time_s", seconds(now - start_ns_)},
      {"camera", pipeline.describe_source()},
      {"side_camera",
       side ? nlohmann::json{{"camera", side->describe()}, {"connected", side->connected()}} : nlohmann::json(nullptr)},
      {"fps", drive.fps},
      {"source", std::string(drive_source_name(status_source(drive.status)))},
      {"frames",
       {{"captured", s.captured},
        {"processed", s.processed},
        {"tracked", s.tracked},
        {"dropped", s.dropped},
        {"lost_track", s.lost_track},
        {"disconnects", s.disconnects},
        {"corrupt", s.corrupt}}},
      {"latency_ms",
       {{"processed", {{"median", s.processed_median_ms}, {"p99", s.processed_p99_ms}}},
        {"output", {{"median", s.output_median_ms}, {"p99", s.output_p99_ms}}}}},
      {"status",
       {{"word", drive.status},
        {"tracking", bit(kStatusTracking)},
        {"calibrated", bit(kStatusCalibrated)},
        {"fail_safe", bit(kStatusFailSafe)},
        {"side_camera", bit(kStatusSideCamera)},
        {"recording", bit(kStatusRecording)},
        {"outputs_enabled", bit(kStatusOutputsEnabled)},
        {"camera_connected", bit(kStatusCameraConnected)},
        {"model_mismatch", bit(kStatusModelMismatch)}}},
      {"mouth",
       {{"tracked", tracked},
        {"open", tracked ? result.measures.open : 0.0},
        {"width", tracked ? result.measures.width_fit : 0.0},
        {"seal", tracked ? result.measures.seal : 0.0},
        {"protrusion", tracked ? (result.side_used ? result.protrusion_side : result.measures.protrusion_3d) : 0.0}}},
      {"channels", std::move(channels)},
      {"outputs", std::move(outputs)},
      {"performer",
       {{"name", sources_.performer},
        {"model_mismatch", sources_.model_mismatch},
        {"warning", sources_.model_mismatch ? "the performer's mouth and the model's are two height classes "
                                              "apart: expect clearly worse lips (docs/method.md 6)"
                                            : ""}}},
      {"commands",
       {{"calibrate_requests", sources_.control.calibrate_requests.load()},
        {"calibrations", calibrations},
        {"recording_request", sources_.control.recording_request.load()},
        {"outputs_enabled", sources_.control.outputs_enabled.load()},
        {"enable_switch", sources_.control.enable_switch_closed.load()}}},
      {"timecode", drive.timecode >= 0
                       ? nlohmann::json(std::string(format_frame(drive.timecode, drive.timecode_rate).view()))
                       : nlohmann::json(nullptr)},
      {"monitor",
       {{"requests", counters_.requests.load()},
        {"turned_away", counters_.turned_away.load()},
        {"refused", counters_.refused.load()},
        {"commands", counters_.commands.load()},
        {"previews", counters_.encoded.load()}}},
  };
  state_ = std::make_shared<const std::string>(state.dump());
  state_time_ns_ = now;
  return state_;
}

}  // namespace lipdrive
