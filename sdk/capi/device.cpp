// sls_device_list: the device registry's enumeration (drivers/device_registry.h) as an
// immutable snapshot whose strings live as long as the list.
#include <cstddef>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "drivers/device_registry.h"
#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/versioned_struct.h"
#include "sls/sls_device.h"

struct sls_device_list {
  std::vector<sls::drivers::DeviceDescription> devices;
  bool hardware_found = false;
  std::string problems;
};

namespace {

// The public enum and bits mirror the registry's; keep them equal.
static_assert(static_cast<unsigned>(SLS_DEVICE_ROLE_CAMERA) == sls::drivers::kRoleCamera);
static_assert(static_cast<unsigned>(SLS_DEVICE_ROLE_PROJECTOR) == sls::drivers::kRoleProjector);
static_assert(static_cast<unsigned>(SLS_DEVICE_ROLE_TURNTABLE) == sls::drivers::kRoleTurntable);

sls_device_kind to_c(sls::drivers::DeviceKind kind) {
  switch (kind) {
    case sls::drivers::DeviceKind::kCamera: return SLS_DEVICE_KIND_CAMERA;
    case sls::drivers::DeviceKind::kProjector: return SLS_DEVICE_KIND_PROJECTOR;
    case sls::drivers::DeviceKind::kController: return SLS_DEVICE_KIND_CONTROLLER;
    case sls::drivers::DeviceKind::kScanner: return SLS_DEVICE_KIND_SCANNER;
  }
  sls::throw_error(sls::ErrorCode::kInternal, "device kind {} has no C value", static_cast<int>(kind));
}

constexpr std::size_t kDeviceInfoFirstVersionSize = offsetof(sls_device_info, roles) + sizeof(unsigned int);

}  // namespace

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_device_info, roles, sls::capi::zeroed<sls_device_info>())

SLS_API sls_status sls_device_list_create(sls_context* context, sls_device_list** list, sls_error** error) {
  SLS_CAPI_REQUIRE(list != nullptr, error, "list (the output pointer) is NULL");
  *list = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls::drivers::DeviceEnumeration found = sls::drivers::enumerate_devices();
    auto created = std::make_unique<sls_device_list>();
    created->hardware_found = found.hardware_found();
    created->devices = std::move(found.devices);
    for (const sls::drivers::TransportSearch& transport : found.transports) {
      if (!transport.searched) created->problems += transport.name + ": " + transport.problem + "\n";
    }
    *list = created.release();
  });
}

SLS_API void sls_device_list_destroy(sls_device_list* list) { delete list; }

SLS_API sls_status sls_device_list_count(const sls_device_list* list, size_t* count, sls_error** error) {
  SLS_CAPI_REQUIRE(list != nullptr, error, "list is NULL");
  SLS_CAPI_REQUIRE(count != nullptr, error, "count (the output pointer) is NULL");
  *count = list->devices.size();
  return SLS_OK;
}

SLS_API sls_status sls_device_list_get_info(const sls_device_list* list, size_t index, sls_device_info* info,
                                            sls_error** error) {
  SLS_CAPI_REQUIRE(list != nullptr, error, "list is NULL");
  SLS_CAPI_REQUIRE(info != nullptr, error, "info (the output pointer) is NULL");
  if (index >= list->devices.size()) {
    return sls::capi::report(SLS_ERROR_INVALID_ARGUMENT, __func__,
                             "index " + std::to_string(index) + " is past the list's " +
                                 std::to_string(list->devices.size()) + " devices",
                             error);
  }
  return sls::capi::guarded(__func__, error, [&] {
    const sls::drivers::DeviceDescription& device = list->devices[index];
    sls_device_info filled;
    sls_device_info_init(&filled);
    filled.kind = to_c(device.kind);
    filled.uri = device.uri.c_str();
    filled.model = device.model.c_str();
    filled.serial = device.serial.c_str();
    filled.details = device.details.c_str();
    filled.roles = device.roles;
    sls::capi::write_versioned(filled, info, kDeviceInfoFirstVersionSize, "sls_device_info");
  });
}

SLS_API sls_status sls_device_list_has_hardware(const sls_device_list* list, int* has_hardware, sls_error** error) {
  SLS_CAPI_REQUIRE(list != nullptr, error, "list is NULL");
  SLS_CAPI_REQUIRE(has_hardware != nullptr, error, "has_hardware (the output pointer) is NULL");
  *has_hardware = list->hardware_found ? 1 : 0;
  return SLS_OK;
}

SLS_API sls_status sls_device_list_problems(const sls_device_list* list, const char** problems, sls_error** error) {
  SLS_CAPI_REQUIRE(list != nullptr, error, "list is NULL");
  SLS_CAPI_REQUIRE(problems != nullptr, error, "problems (the output pointer) is NULL");
  *problems = list->problems.c_str();
  return SLS_OK;
}

}  // extern "C"
