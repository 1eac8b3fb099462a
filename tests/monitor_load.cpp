// Load for the monitor page (scripts/monitor-latency.sh, docs/monitor.md): N clients poll
// /api/state at a given rate, each on its own thread with its own connections, as scripts or
// dashboards would, for a given time, until SIGTERM or SIGINT, or until the monitor goes away
// (a client stops at its first refused connection: the daemon has exited). Prints what they
// got; exits 0 when every answer was 200.
//
//   monitor_load --port 8480 [--clients 50] [--hz 5] [--seconds 60]
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <httplib.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

namespace {

std::atomic<bool> stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "set from a signal handler");

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Polls the monitor's /api/state from many clients at once");
  int port = 8480, clients = 50;
  double hz = 5, seconds = 60;
  app.add_option("--port", port, "the monitor's port on 127.0.0.1")->required();
  app.add_option("--clients", clients, "clients polling at once")->check(CLI::Range(1, 1000));
  app.add_option("--hz", hz, "polls a second per client")->check(CLI::Range(0.1, 100.0));
  app.add_option("--seconds", seconds, "how long")->check(CLI::Range(0.1, 86400.0));
  CLI11_PARSE(app, argc, argv);
  for (const int signal : {SIGTERM, SIGINT}) std::signal(signal, [](int) { stop = true; });

  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  const Clock::time_point end =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / hz));
  std::atomic<int> gone{0};  // clients that found the monitor gone
  std::mutex mutex;
  std::map<std::string, long> answers;  // status code or error -> count
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i) {
    threads.emplace_back([&, i] {
      httplib::Client client("127.0.0.1", port);
      client.set_connection_timeout(2, 0);
      client.set_read_timeout(2, 0);
      // Spread the clients over the period instead of all at once.
      Clock::time_point next = Clock::now() + period * i / clients;
      std::map<std::string, long> mine;
      while (next < end && !stop) {
        std::this_thread::sleep_until(next);
        next += period;
        const httplib::Result result = client.Get("/api/state");
        if (!result && result.error() == httplib::Error::Connection) {
          ++gone;
          break;
        }
        ++mine[result ? std::to_string(result->status) : httplib::to_string(result.error())];
      }
      std::lock_guard lock(mutex);
      for (const auto& [answer, count] : mine) answers[answer] += count;
    });
  }
  for (std::thread& thread : threads) thread.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  long total = 0;
  for (const auto& [answer, count] : answers) total += count;
  fmt::print("monitor_load: {} clients at {} Hz for {:.1f} s: {} requests", clients, hz, elapsed, total);
  for (const auto& [answer, count] : answers) fmt::print(", {} {}", count, answer);
  if (gone > 0) fmt::print("; {} clients then found the monitor gone", gone.load());
  fmt::print("\n");
  return answers.size() == 1 && answers.contains("200") ? 0 : 1;
}
