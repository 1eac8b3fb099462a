// Headless Chromium for the page tests, driven through chromedriver's W3C WebDriver protocol
// (Debian's chromium and chromium-driver; scripts/install-deps.sh installs them). As root,
// Chromium needs --no-sandbox; the other flags keep it off the network and start it fresh.
#pragma once

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <openssl/evp.h>

#include <algorithm>
#include <chrono>
#include <fcntl.h>
#include <filesystem>
#include <signal.h>
#include <spawn.h>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace lipdrive::test {

/// A chromedriver process and one browser session in it.
class WebDriver {
 public:
  /// Starts chromedriver on `port` (its log in `dir`) and a headless session with its profile in
  /// `dir`. ok() tells whether it worked; why() says what failed.
  WebDriver(const std::filesystem::path& dir, int port) : http_("127.0.0.1", port) {
    http_.set_read_timeout(60, 0);
    const std::string log = (dir / "chromedriver.log").string();
    std::vector<std::string> args = {"/usr/bin/chromedriver", fmt::format("--port={}", port), "--log-path=" + log};
    std::vector<char*> argv;
    for (auto& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) {
      why_ = "cannot start /usr/bin/chromedriver (package chromium-driver)";
      pid_ = -1;
    }
    posix_spawn_file_actions_destroy(&actions);
    if (pid_ < 0) return;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (true) {
      const httplib::Result status = http_.Get("/status");
      if (status && status->status == 200 && nlohmann::json::parse(status->body)["value"]["ready"] == true) break;
      if (std::chrono::steady_clock::now() > deadline) {
        why_ = "chromedriver did not become ready";
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    const nlohmann::json capabilities = {
        {"capabilities",
         {{"alwaysMatch",
           {{"browserName", "chrome"},
            {"goog:chromeOptions",
             {{"binary", "/usr/bin/chromium"},
              {"args",
               {"--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", "--window-size=1280,1000",
                "--user-data-dir=" + (dir / "chromium-profile").string()}}}}}}}}};
    const nlohmann::json session = command("POST", "/session", capabilities);
    if (session.contains("sessionId")) session_ = session["sessionId"];
    if (session_.empty()) why_ = "no browser session: " + session.dump();
  }
  ~WebDriver() {
    if (!session_.empty()) http_.Delete(("/session/" + session_).c_str());
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  WebDriver(const WebDriver&) = delete;
  WebDriver& operator=(const WebDriver&) = delete;

  bool ok() const { return !session_.empty(); }
  const std::string& why() const { return why_; }

  void go(const std::string& url) { session_command("POST", "/url", {{"url", url}}); }
  /// The value a script returns (`return ...;`).
  nlohmann::json execute(const std::string& script) {
    return session_command("POST", "/execute/sync", {{"script", script}, {"args", nlohmann::json::array()}});
  }
  void click(const std::string& css) { session_command("POST", "/element/" + element(css) + "/click", {}); }
  /// The window's outer size in CSS pixels.
  void set_window_size(int width, int height) {
    session_command("POST", "/window/rect", {{"width", width}, {"height", height}});
  }
  /// The element's box in CSS pixels: x, y, width, height.
  nlohmann::json rect(const std::string& css) { return session_command("GET", "/element/" + element(css) + "/rect"); }
  /// The viewport as PNG bytes.
  std::string screenshot_png() {
    const std::string base64 = session_command("GET", "/screenshot");
    std::string png(base64.size() / 4 * 3, '\0');
    const int size =
        EVP_DecodeBlock(reinterpret_cast<unsigned char*>(png.data()),
                        reinterpret_cast<const unsigned char*>(base64.data()), static_cast<int>(base64.size()));
    if (size < 0) return {};
    // EVP_DecodeBlock counts the '=' padding as zero bytes.
    png.resize(static_cast<std::size_t>(size) -
               static_cast<std::size_t>(
                   std::count(base64.end() - std::min<std::size_t>(base64.size(), 2), base64.end(), '=')));
    return png;
  }

 private:
  std::string element(const std::string& css) {
    const nlohmann::json found = session_command("POST", "/element", {{"using", "css selector"}, {"value", css}});
    EXPECT_TRUE(found.is_object() && !found.empty()) << css << ": " << found.dump();
    return found.is_object() && !found.empty() ? found.begin().value().get<std::string>() : "";
  }
  nlohmann::json session_command(const std::string& method, const std::string& path,
                                 const nlohmann::json& body = nullptr) {
    const nlohmann::json answer = command(method, "/session/" + session_ + path, body);
    EXPECT_FALSE(answer.is_object() && answer.contains("error")) << method << " " << path << ": " << answer.dump();
    return answer;
  }
  /// The "value" of a WebDriver answer (an object with "error" when it failed).
  nlohmann::json command(const std::string& method, const std::string& path, const nlohmann::json& body) {
    const httplib::Result result =
        method == "GET" ? http_.Get(path.c_str())
                        : http_.Post(path.c_str(), body.is_null() ? "{}" : body.dump(), "application/json");
    if (!result) return {{"error", httplib::to_string(result.error())}};
    const nlohmann::json answer = nlohmann::json::parse(result->body, nullptr, false);
    return answer.is_object() && answer.contains("value") ? answer["value"] : nlohmann::json{{"error", result->body}};
  }

  httplib::Client http_;
  pid_t pid_ = -1;
  std::string session_, why_;
};

}  // namespace lipdrive::test
