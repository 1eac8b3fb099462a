// A test's log kept in memory (spdlog's default logger swapped for the test's lifetime), so
// that tests can count messages and read what they say.
#pragma once

#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <string>
#include <vector>

namespace lipdrive::testing {

class CapturedLog {
 public:
  CapturedLog() : sink_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(100)), previous_(spdlog::default_logger()) {
    auto logger = std::make_shared<spdlog::logger>("test", sink_);
    logger->set_level(spdlog::level::debug);
    spdlog::set_default_logger(logger);
  }
  ~CapturedLog() { spdlog::set_default_logger(previous_); }
  CapturedLog(const CapturedLog&) = delete;
  CapturedLog& operator=(const CapturedLog&) = delete;

  int count(spdlog::level::level_enum level) const {
    int n = 0;
    for (const auto& message : sink_->last_raw()) n += message.level == level;
    return n;
  }

  /// The messages at `level`, oldest first.
  std::vector<std::string> messages(spdlog::level::level_enum level) const {
    std::vector<std::string> texts;
    for (const auto& message : sink_->last_raw())
      if (message.level == level) texts.emplace_back(message.payload.begin(), message.payload.end());
    return texts;
  }

 private:
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
  std::shared_ptr<spdlog::logger> previous_;
};

}  // namespace lipdrive::testing
