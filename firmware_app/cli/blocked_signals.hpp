// Signals a command takes when it looks for them instead of being ended by them where it
// stands: blocked before the command starts a thread (each thread inherits the mask, so no
// thread of its own or of a library's is interrupted), then taken on the command's thread.
#pragma once

#include <csignal>
#include <ctime>
#include <initializer_list>

namespace lipdrive {

class BlockedSignals {
 public:
  /// Blocks `numbers` in the calling thread and so in every thread it starts from now on. They
  /// stay blocked for the rest of the process: one unblocked while pending would act at once.
  explicit BlockedSignals(std::initializer_list<int> numbers) {
    sigemptyset(&set_);
    for (const int number : numbers) sigaddset(&set_, number);
    pthread_sigmask(SIG_BLOCK, &set_, nullptr);
  }

  /// The signal that arrived first, waiting up to `timeout` for one (none: returns at once);
  /// 0 when none did.
  int take(const timespec& timeout = {0, 0}) const {
    const int number = sigtimedwait(&set_, nullptr, &timeout);
    return number > 0 ? number : 0;
  }

 private:
  sigset_t set_;
};

}  // namespace lipdrive
