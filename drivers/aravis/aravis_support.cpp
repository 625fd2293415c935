// Discovery of GigE Vision and USB3 Vision cameras through Aravis, and what the camera
// (aravis_camera.cpp) shares with it (aravis_support.h).
#include "drivers/aravis/aravis_support.h"

#include <arv.h>

#include <memory>
#include <utility>

namespace sls::drivers {
namespace aravis_support {

std::mutex& aravis_system_mutex() {
  static std::mutex mutex;
  return mutex;
}

std::string text_or_empty(const char* text) { return text != nullptr ? std::string(text) : std::string(); }

GErrorSlot::~GErrorSlot() { g_clear_error(&error_); }

GError** GErrorSlot::out() {
  g_clear_error(&error_);
  return &error_;
}

void GFreeDeleter::operator()(void* pointer) const { g_free(pointer); }

ErrorCode error_code_for(const GError& error) {
  if (error.domain == ARV_DEVICE_ERROR) {
    switch (error.code) {
      case ARV_DEVICE_ERROR_TIMEOUT:
        return ErrorCode::kTimeout;
      case ARV_DEVICE_ERROR_NOT_FOUND:
        return ErrorCode::kNotFound;
      case ARV_DEVICE_ERROR_FEATURE_NOT_FOUND:
      case ARV_DEVICE_ERROR_WRONG_FEATURE:
      case ARV_DEVICE_ERROR_PROTOCOL_ERROR_NOT_IMPLEMENTED:
        return ErrorCode::kUnsupported;
      case ARV_DEVICE_ERROR_NOT_CONTROLLER:
      case ARV_DEVICE_ERROR_PROTOCOL_ERROR_BUSY:
      case ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED:
        return ErrorCode::kBusy;
      case ARV_DEVICE_ERROR_INVALID_PARAMETER:
      case ARV_DEVICE_ERROR_PROTOCOL_ERROR_INVALID_PARAMETER:
        return ErrorCode::kInvalidArgument;
      default:
        return ErrorCode::kDevice;
    }
  }
  if (error.domain == ARV_GC_ERROR) {
    switch (error.code) {
      case ARV_GC_ERROR_OUT_OF_RANGE:
      case ARV_GC_ERROR_ENUM_ENTRY_NOT_FOUND:
      case ARV_GC_ERROR_READ_ONLY:
        return ErrorCode::kInvalidArgument;
      case ARV_GC_ERROR_NODE_NOT_FOUND:
        return ErrorCode::kUnsupported;
      default:
        return ErrorCode::kDevice;
    }
  }
  return ErrorCode::kDevice;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out.empty() ? std::string("none") : out;
}

std::vector<std::string> take_string_array(const char** strings, unsigned count) {
  std::unique_ptr<const char*, GFreeDeleter> owner(strings);
  std::vector<std::string> out;
  for (unsigned i = 0; strings != nullptr && i < count; ++i) out.push_back(text_or_empty(strings[i]));
  return out;
}

std::vector<DiscoveredCamera> discover_locked() {
  arv_update_device_list();
  std::vector<DiscoveredCamera> cameras;
  const unsigned count = arv_get_n_devices();
  for (unsigned i = 0; i < count; ++i) {
    DiscoveredCamera camera;
    camera.id = text_or_empty(arv_get_device_id(i));
    camera.vendor = text_or_empty(arv_get_device_vendor(i));
    camera.model = text_or_empty(arv_get_device_model(i));
    camera.serial = text_or_empty(arv_get_device_serial_nbr(i));
    camera.address = text_or_empty(arv_get_device_address(i));
    camera.protocol = text_or_empty(arv_get_device_protocol(i));
    // Only real transports: Aravis's "Fake" interface (off by default) is no camera.
    if (camera.protocol == "GigEVision" || camera.protocol == "USB3Vision") cameras.push_back(std::move(camera));
  }
  return cameras;
}


}  // namespace aravis_support

std::string DiscoveredCamera::uri() const {
  if (protocol == "USB3Vision") return "usb3://" + (serial.empty() ? id : serial);
  return "gige://" + (address.empty() ? id : address);
}

std::vector<DiscoveredCamera> discover_aravis_cameras() {
  std::lock_guard<std::mutex> lock(aravis_support::aravis_system_mutex());
  return aravis_support::discover_locked();
}

}  // namespace sls::drivers
