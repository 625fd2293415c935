#include "sdk/core/log.h"

#include <spdlog/details/log_msg.h>
#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/sink.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "sdk/core/error.h"

namespace sls {
namespace {

// Set while this thread runs the handler: its own messages are dropped and it may not swap the
// handler (the sink's lock is held, so that would wait for itself).
thread_local bool t_in_handler = false;

// stderr, or the handler. Its own lock, checked for recursion first: a handler that calls into
// the SDK, which logs on the same thread, must not wait for itself.
class HandlerSink final : public spdlog::sinks::sink {
 public:
  void set(LogHandler handler, void* user) {
    require_not_in_log_handler();
    const std::lock_guard<std::mutex> lock(mutex_);
    handler_ = handler;
    user_ = user;
  }

  void log(const spdlog::details::log_msg& msg) override {
    if (t_in_handler) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    if (handler_ == nullptr) {
      spdlog::memory_buf_t line;
      formatter_->format(msg, line);
      std::fwrite(line.data(), 1, line.size(), stderr);
      return;
    }
    const std::string text(msg.payload.data(), msg.payload.size());
    t_in_handler = true;
    handler_(msg.level, text.c_str(), user_);
    t_in_handler = false;
  }
  void flush() override { std::fflush(stderr); }
  void set_pattern(const std::string& pattern) override {
    set_formatter(std::make_unique<spdlog::pattern_formatter>(pattern));
  }
  void set_formatter(std::unique_ptr<spdlog::formatter> formatter) override {
    const std::lock_guard<std::mutex> lock(mutex_);
    formatter_ = std::move(formatter);
  }

 private:
  std::mutex mutex_;
  std::unique_ptr<spdlog::formatter> formatter_ = std::make_unique<spdlog::pattern_formatter>();
  LogHandler handler_ = nullptr;
  void* user_ = nullptr;
};

struct Log {
  std::shared_ptr<HandlerSink> sink = std::make_shared<HandlerSink>();
  std::shared_ptr<spdlog::logger> logger = std::make_shared<spdlog::logger>("slscan", sink);

  Log() {
    logger->set_level(spdlog::level::warn);
    // Registered for spdlog::set_level(); a host that already registered the name keeps its own.
    try {
      spdlog::register_logger(logger);
    } catch (const spdlog::spdlog_ex&) {
    }
  }
};

Log& the_log() {
  // Never destroyed: a static destructor elsewhere may still log.
  static Log* const log = new Log();
  return *log;
}

// Made and registered when the program starts, not at the first message: a spdlog::set_level()
// in main() (the `sls` tool's -v, -q) then reaches it.
[[maybe_unused]] const bool g_registered_at_start = (the_log(), true);

}  // namespace

spdlog::logger& logger() { return *the_log().logger; }

void require_not_in_log_handler() {
  if (t_in_handler) throw_error(ErrorCode::kBusy, "the log handler cannot be changed from inside the log handler");
}

void set_log_handler(LogHandler handler, void* user) { the_log().sink->set(handler, user); }

}  // namespace sls
