// Names and scheduling of a thread: a thin wrapper over pthread_setname_np and
// pthread_setschedparam.
//
// The frame path's threads (capture, processing, output) run under SCHED_FIFO when the
// configuration asks for it ([scheduling] realtime_priority): a compiler, a log rotation or the
// monitor's image encoder then cannot delay a frame, only share what the frame path leaves. The
// kernel's real-time throttling (sched_rt_runtime_us, 95 % by default) still leaves the rest of
// the system its share if a real-time thread were ever to spin.
#pragma once

#include <string>
#include <thread>

namespace lipdrive {

/// Names `thread` for top -H, ps -L and gdb (the kernel keeps the first 15 characters).
void name_thread(std::thread& thread, const char* name);

/// Names `thread` and, when `realtime_priority` is 1..99, puts it under SCHED_FIFO at that
/// priority (0: the normal scheduler). Returns "" when done, otherwise why the priority was
/// refused (the thread runs on under the normal scheduler): a process needs CAP_SYS_NICE, or
/// RLIMIT_RTPRIO of at least the priority (systemd's LimitRTPRIO= with RestrictRealtime=no).
std::string schedule_thread(std::thread& thread, const char* name, int realtime_priority);

}  // namespace lipdrive
