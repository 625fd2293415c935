// The SDK's log: every part of the SDK writes its warnings and diagnostics through logger(), one
// spdlog logger named "slscan", which prints to stderr unless a handler is set (the C API's
// sls_set_log_callback). Its own logger, not spdlog's default one: libspdlog is a shared library,
// so a host program's own spdlog use must neither receive slscan's messages nor redirect them.
// It is registered with spdlog, so spdlog::set_level() (the `sls` tool's -v/-q) applies to it.
#pragma once

#include <spdlog/logger.h>

namespace sls {

spdlog::logger& logger();

// Receives each message at or above the logger's level, without the stderr line's decorations,
// on the thread that logged it; calls are serialised. A message the handler's own thread logs
// while inside the handler is dropped (no recursion).
using LogHandler = void (*)(spdlog::level::level_enum level, const char* message, void* user);

// Sends messages to `handler` (nullptr: back to stderr). Throws sls::Error(kBusy) when called from
// inside the handler. Once it returns, the previous handler is no longer called.
void set_log_handler(LogHandler handler, void* user);

// Throws sls::Error(kBusy) on a thread that is inside the log handler.
void require_not_in_log_handler();

}  // namespace sls
