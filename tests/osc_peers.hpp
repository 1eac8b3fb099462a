// A test-side OSC peer: a liblo server on a free port that keeps every bundle it receives.
#pragma once

#include <lo/lo.h>

#include <chrono>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive::test {

/// An OSC receiver on a free port (liblo's server thread) that keeps every bundle:
/// its time tag and its messages' addresses and first arguments.
class OscCapture {
 public:
  struct Message {
    std::string address;
    std::string types;
    float number = 0;  // first argument, when numeric
    std::string text;  // first argument, when a string
  };
  struct Bundle {
    lo_timetag time_tag{};
    std::chrono::system_clock::time_point received;
    std::vector<Message> messages;
  };

  OscCapture() {
    server_ = lo_server_thread_new_with_proto(nullptr, LO_UDP, nullptr);
    if (!server_) throw std::runtime_error("OscCapture: no liblo server");
    lo_server_add_bundle_handlers(lo_server_thread_get_server(server_), &OscCapture::bundle_start,
                                  &OscCapture::bundle_end, this);
    lo_server_thread_add_method(server_, nullptr, nullptr, &OscCapture::message, this);
    lo_server_thread_start(server_);
  }
  ~OscCapture() {
    lo_server_thread_stop(server_);
    lo_server_thread_free(server_);
  }
  OscCapture(const OscCapture&) = delete;
  OscCapture& operator=(const OscCapture&) = delete;

  int port() const { return lo_server_thread_get_port(server_); }
  std::vector<Bundle> bundles() const {
    std::lock_guard lock(mutex_);
    return bundles_;
  }
  /// Messages that arrived outside any bundle.
  std::vector<Message> loose_messages() const {
    std::lock_guard lock(mutex_);
    return loose_;
  }

 private:
  static int bundle_start(lo_timetag time, void* self) {
    auto* capture = static_cast<OscCapture*>(self);
    std::lock_guard lock(capture->mutex_);
    capture->open_ = Bundle{time, std::chrono::system_clock::now(), {}};
    return 0;
  }
  static int bundle_end(void* self) {
    auto* capture = static_cast<OscCapture*>(self);
    std::lock_guard lock(capture->mutex_);
    if (capture->open_) capture->bundles_.push_back(std::move(*capture->open_));
    capture->open_.reset();
    return 0;
  }
  static int message(const char* path, const char* types, lo_arg** argv, int argc, lo_message, void* self) {
    auto* capture = static_cast<OscCapture*>(self);
    Message m{path, types, 0, {}};
    if (argc > 0) {
      if (types[0] == LO_FLOAT) m.number = argv[0]->f;
      if (types[0] == LO_INT32) m.number = static_cast<float>(argv[0]->i);
      if (types[0] == LO_STRING) m.text = &argv[0]->s;
    }
    std::lock_guard lock(capture->mutex_);
    if (capture->open_)
      capture->open_->messages.push_back(std::move(m));
    else
      capture->loose_.push_back(std::move(m));
    return 0;
  }

  lo_server_thread server_ = nullptr;
  mutable std::mutex mutex_;
  std::optional<Bundle> open_;
  std::vector<Bundle> bundles_;
  std::vector<Message> loose_;
};

}  // namespace lipdrive::test
