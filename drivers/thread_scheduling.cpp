#include "drivers/thread_scheduling.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>

#include <cstring>

namespace lipdrive {

void name_thread(std::thread& thread, const char* name) {
  char truncated[16] = {};
  std::strncpy(truncated, name, sizeof truncated - 1);
  pthread_setname_np(thread.native_handle(), truncated);
}

std::string schedule_thread(std::thread& thread, const char* name, int realtime_priority) {
  name_thread(thread, name);
  if (realtime_priority <= 0) return "";
  sched_param param{};
  param.sched_priority = realtime_priority;
  const int error = pthread_setschedparam(thread.native_handle(), SCHED_FIFO, &param);
  if (error == 0) return "";
  return fmt::format("{}: SCHED_FIFO priority {} refused: {}", name, realtime_priority, std::strerror(error));
}

}  // namespace lipdrive
