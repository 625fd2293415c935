// What drivers/aravis shares between its discovery and its camera (internal to the folder):
// the lock over Aravis's global device list, GLib's errors and string arrays owned, and
// Aravis's error codes as the SDK's. GLib's types are named, not included (arv.h stays in the
// sources): GLib's GError is `struct _GError`.
#pragma once

#include <mutex>
#include <string>
#include <vector>

#include "drivers/aravis/aravis_camera.h"
#include "sdk/core/error.h"

struct _GError;  // NOLINT(bugprone-reserved-identifier): GLib's name for GError

namespace sls::drivers::aravis_support {

// Aravis's device list (discovery) and camera creation use global state that is not
// thread-safe; every call into them holds this lock.
std::mutex& aravis_system_mutex();

std::string text_or_empty(const char* text);

// Owns the GError an Aravis call may set, so that no path leaks it.
class GErrorSlot {
 public:
  GErrorSlot() = default;
  ~GErrorSlot();
  GErrorSlot(const GErrorSlot&) = delete;
  GErrorSlot& operator=(const GErrorSlot&) = delete;

  _GError** out();  // cleared first
  bool failed() const { return error_ != nullptr; }
  const _GError* get() const { return error_; }

 private:
  _GError* error_ = nullptr;
};

// Frees a NULL-terminated or counted array of strings Aravis hands over with g_free.
struct GFreeDeleter {
  void operator()(void* pointer) const;
};

ErrorCode error_code_for(const _GError& error);

// "a, b, c", or "none".
std::string join(const std::vector<std::string>& items);

// Strings from an Aravis "dup_available_..." call (array freed with g_free, strings not owned).
std::vector<std::string> take_string_array(const char** strings, unsigned count);

// The GigE Vision and USB3 Vision cameras Aravis lists now; aravis_system_mutex() held.
std::vector<DiscoveredCamera> discover_locked();

}  // namespace sls::drivers::aravis_support
