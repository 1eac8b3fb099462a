#include "firmware_app/daemon/take_recorder.hpp"

#include "drivers/thread_scheduling.hpp"
#include "firmware_app/tables/measures_csv.hpp"

#include <spdlog/spdlog.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <utility>

namespace lipdrive {

std::filesystem::path take_file_name(const std::filesystem::path& dir, const std::string& name) {
  std::string stem = name;
  if (stem.empty()) {
    const std::time_t now = std::time(nullptr);
    std::tm local{};
    ::localtime_r(&now, &local);
    char stamp[32];
    std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", &local);
    stem = fmt::format("take-{}", stamp);
  }
  // Two takes in one second (a quick reload) or under one slate must not overwrite each other.
  std::filesystem::path file = dir / fmt::format("{}.csv", stem);
  std::error_code ec;
  for (int n = 2; std::filesystem::exists(file, ec); ++n) file = dir / fmt::format("{}-{}.csv", stem, n);
  return file;
}

TakeRecorder::TakeRecorder(std::string source, std::chrono::milliseconds flush_interval,
                           std::optional<TimecodeRate> timecode_rate, TakeSound* sound)
    : source_(std::move(source)),
      flush_interval_(flush_interval),
      timecode_rate_(timecode_rate),
      sound_(sound),
      thread_(&TakeRecorder::run, this) {
  name_thread(thread_, "lipdrive-take");
}

TakeRecorder::~TakeRecorder() {
  active_ = false;
  {
    std::lock_guard lock(mutex_);
    quit_ = true;
  }
  thread_.join();
}

void TakeRecorder::start(const std::filesystem::path& file) {
  std::lock_guard lock(mutex_);
  start_request_ = file;
  stop_request_ = false;
  error_.reset();
  active_ = true;
}

void TakeRecorder::stop() {
  std::lock_guard lock(mutex_);
  active_ = false;
  start_request_.reset();
  stop_request_ = true;
}

std::optional<std::string> TakeRecorder::error() const {
  std::lock_guard lock(mutex_);
  return error_;
}

void TakeRecorder::push(const FrameResult& result) {
  if (!active_.load(std::memory_order_acquire)) return;
  ring_.push(result);
}

void TakeRecorder::run() {
  for (;;) {
    bool quit = false;
    {
      std::lock_guard lock(mutex_);
      quit = quit_;
    }
    apply_request();
    drain();
    if (sound_) sound_->drain();
    if (fd_.valid() && std::chrono::steady_clock::now() - last_sync_ >= flush_interval_) {
      struct stat file {};
      if (::fdatasync(fd_.get()) != 0)
        fail(fmt::format("{}: recording stopped: {}", file_.string(), std::strerror(errno)));
      else if (::fstat(fd_.get(), &file) == 0 && file.st_nlink == 0)
        // Writes to a file whose last name is gone succeed and reach nothing anyone can open.
        fail(fmt::format("{}: recording stopped: the file was removed (its folder deleted?)", file_.string()));
      last_sync_ = std::chrono::steady_clock::now();
    }
    if (quit) break;
    // The ring holds far more than one nap's worth of frames.
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  close_take();
}

void TakeRecorder::apply_request() {
  std::optional<std::filesystem::path> start;
  bool stop = false;
  {
    std::lock_guard lock(mutex_);
    start = std::exchange(start_request_, std::nullopt);
    stop = std::exchange(stop_request_, false);
  }
  // Rows queued before the request belong to the take that is open, if any.
  if (stop || (start && fd_.valid())) {
    drain();
    close_take();
  }
  if (start) open_take(*start);
}

void TakeRecorder::open_take(const std::filesystem::path& file) {
  std::error_code ec;
  if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path(), ec);
  file_ = file;
  fd_ = UniqueFd(::open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640));
  if (!fd_.valid()) {
    fail(fmt::format("{}: cannot record a take: {}", file.string(), std::strerror(errno)));
    return;
  }
  last_sync_ = std::chrono::steady_clock::now();
  spdlog::info("recording a take to {}", file.string());
  last_row_ns_.reset();
  if (sound_) {
    sound_->open(std::filesystem::path(file).replace_extension(".wav"));
    sound_zero_pending_ = true;
  }
  // With a timecode the header names the first row's, so it waits for that row.
  header_pending_ = true;
  if (timecode_rate_) return;
  lines_.clear();
  append_header(nullptr);
  write_all(lines_.data(), lines_.size());
}

void TakeRecorder::close_take() {
  if (!fd_.valid()) return;
  if (header_pending_) {
    lines_.clear();
    append_header(nullptr);
    write_all(lines_.data(), lines_.size());
  }
  ::fdatasync(fd_.get());
  fd_.reset();
  if (sound_) sound_->close(last_row_ns_);  // the sound ends with the last row
  const std::uint64_t lost = ring_.take_dropped();
  if (lost > 0)
    spdlog::warn("{}: take closed; {} rows were lost because the storage could not keep up", file_.string(), lost);
  else
    spdlog::info("{}: take closed", file_.string());
}

void TakeRecorder::drain() {
  const FrameResult* first = ring_.front();
  if (first == nullptr) return;
  lines_.clear();
  if (fd_.valid() && header_pending_) append_header(first);
  if (fd_.valid() && sound_ && sound_zero_pending_) {
    sound_->start_at(first->capture_time_ns);
    sound_zero_pending_ = false;
  }
  // Without an open take the rows are discarded.
  ring_.consume([&](const FrameResult& r) {
    if (!fd_.valid()) return;
    last_row_ns_ = r.capture_time_ns;
    append_measures_csv_row(lines_, {r.sequence, r.media_time_s, source_}, r.tracked ? &r.measures : nullptr, r.visemes,
                            r.signals.arkit(), nullptr);
    fmt::format_to(std::back_inserter(lines_), ",{},{}", drive_source_name(r.drive), r.capture_time_ns);
    if (timecode_rate_) {
      lines_.push_back(',');
      if (r.timecode >= 0) append_timecode(lines_, r.timecode, *timecode_rate_);
    }
    lines_.push_back('\n');
  });
  if (fd_.valid()) write_all(lines_.data(), lines_.size());
}

void TakeRecorder::append_header(const FrameResult* first) {
  header_pending_ = false;
  if (timecode_rate_) {
    fmt::format_to(std::back_inserter(lines_), "# timecode_start ");
    if (first && first->timecode >= 0)
      append_timecode(lines_, first->timecode, *timecode_rate_);
    else
      fmt::format_to(std::back_inserter(lines_), "none");
    fmt::format_to(std::back_inserter(lines_), " at {} fps\n", rate_name(*timecode_rate_));
  }
  fmt::format_to(std::back_inserter(lines_), "{},drive,capture_time_ns{}\n", measures_csv_header(false),
                 timecode_rate_ ? ",timecode" : "");
}

bool TakeRecorder::write_all(const char* data, std::size_t size) {
  std::size_t done = 0;
  while (done < size) {
    const ssize_t written = ::write(fd_.get(), data + done, size - done);
    if (written < 0 && errno == EINTR) continue;
    if (written < 0) {
      const int error = errno;
      // A disk that filled in the middle of the batch: the part of it that went in ends in the
      // middle of a row. The take is cut back to its last whole row.
      if (const off_t end = ::lseek(fd_.get(), 0, SEEK_CUR); done > 0 && end >= static_cast<off_t>(done)) {
        [[maybe_unused]] const int ignored = ::ftruncate(fd_.get(), end - static_cast<off_t>(done));
      }
      fail(fmt::format("{}: recording stopped: {}; the take ends with its last whole row", file_.string(),
                       std::strerror(error)));
      return false;
    }
    done += static_cast<std::size_t>(written);
  }
  return true;
}

void TakeRecorder::fail(const std::string& message) {
  spdlog::error("{}", message);
  // The take's lost rows are this take's, not the next one's.
  if (const std::uint64_t lost = ring_.take_dropped(); lost > 0)
    spdlog::warn("{}: {} rows were lost before, because the storage could not keep up", file_.string(), lost);
  fd_.reset();
  if (sound_) sound_->close(last_row_ns_);  // the take ended: its sound ends with the last row formatted
  std::lock_guard lock(mutex_);
  // A take asked for since (start() while this one failed) is not this one's: it keeps its rows
  // coming and starts without this error.
  if (start_request_) return;
  active_ = false;
  error_ = message;
}

}  // namespace lipdrive
