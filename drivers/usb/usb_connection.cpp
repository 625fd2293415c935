#include "drivers/usb/usb_connection.h"

#include <libusb.h>

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>

#include "sdk/core/error.h"

namespace sls::drivers::usb {
namespace {

// A libusb context for one scope; every connection has its own, so drivers used from
// different threads never share libusb state.
class Context {
 public:
  Context() {
    const int result = libusb_init(&context_);
    if (result != 0) throw_error(ErrorCode::kDevice, "libusb_init failed: {}", libusb_error_name(result));
  }
  ~Context() {
    if (context_ != nullptr) libusb_exit(context_);
  }
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  libusb_context* get() const { return context_; }
  libusb_context* release() {
    libusb_context* context = context_;
    context_ = nullptr;
    return context;
  }

 private:
  libusb_context* context_ = nullptr;
};

class DeviceList {
 public:
  explicit DeviceList(libusb_context* context) {
    const ssize_t count = libusb_get_device_list(context, &list_);
    if (count < 0) {
      throw_error(ErrorCode::kDevice, "libusb_get_device_list failed: {}", libusb_error_name(static_cast<int>(count)));
    }
    size_ = static_cast<std::size_t>(count);
  }
  ~DeviceList() { libusb_free_device_list(list_, 1); }
  DeviceList(const DeviceList&) = delete;
  DeviceList& operator=(const DeviceList&) = delete;
  libusb_device* operator[](std::size_t i) const { return list_[i]; }
  std::size_t size() const { return size_; }

 private:
  libusb_device** list_ = nullptr;
  std::size_t size_ = 0;
};

std::string string_descriptor(libusb_device_handle* handle, std::uint8_t index) {
  if (index == 0) return {};
  unsigned char text[256] = {};
  const int length = libusb_get_string_descriptor_ascii(handle, index, text, sizeof text);
  if (length <= 0) return {};
  return std::string(reinterpret_cast<const char*>(text), static_cast<std::size_t>(length));
}

UsbDeviceInfo describe_device(libusb_device* device, const libusb_device_descriptor& descriptor,
                              libusb_device_handle* handle) {
  UsbDeviceInfo info;
  info.bus = libusb_get_bus_number(device);
  info.address = libusb_get_device_address(device);
  info.vendor_id = descriptor.idVendor;
  info.product_id = descriptor.idProduct;
  if (handle != nullptr) {
    info.manufacturer = string_descriptor(handle, descriptor.iManufacturer);
    info.product = string_descriptor(handle, descriptor.iProduct);
    info.serial = string_descriptor(handle, descriptor.iSerialNumber);
  }
  return info;
}

bool ids_match(const libusb_device_descriptor& descriptor, std::uint16_t vendor_id, std::uint16_t product_id) {
  return (vendor_id == 0 || descriptor.idVendor == vendor_id) &&
         (product_id == 0 || descriptor.idProduct == product_id);
}

TransferStatus status_of(int result) {
  switch (result) {
    case 0: return TransferStatus::kOk;
    case LIBUSB_ERROR_TIMEOUT: return TransferStatus::kTimeout;
    case LIBUSB_ERROR_PIPE: return TransferStatus::kStall;
    case LIBUSB_ERROR_NO_DEVICE: return TransferStatus::kNoDevice;
    default: return TransferStatus::kError;
  }
}

unsigned int timeout_ms(std::chrono::milliseconds timeout) {
  return static_cast<unsigned int>(std::max<std::chrono::milliseconds::rep>(1, timeout.count()));
}

std::uint16_t parse_id(const std::string& text, const char* key) {
  char* end = nullptr;
  const unsigned long value = std::strtoul(text.c_str(), &end, 0);  // 0x prefix: hex
  if (text.empty() || end == nullptr || *end != '\0' || value > 0xFFFF) {
    throw_error(ErrorCode::kInvalidArgument, "USB device URI: {}={} is not a 16-bit ID (e.g. 0x0451)", key, text);
  }
  return static_cast<std::uint16_t>(value);
}

}  // namespace

std::string UsbSelector::describe() const {
  std::string text = fmt::format("{:04x}:{:04x}", vendor_id, product_id);
  if (bus != 0 || address != 0) text += fmt::format(" on bus {} address {}", bus, address);
  if (!serial.empty()) text += fmt::format(" with serial {}", serial);
  return text;
}

UsbSelector usb_selector_from_uri(const DeviceUri& uri, std::uint16_t default_vendor_id,
                                  std::uint16_t default_product_id) {
  UsbSelector selector;
  selector.vendor_id = default_vendor_id;
  selector.product_id = default_product_id;
  if (!uri.target.empty()) {
    const std::size_t colon = uri.target.find(':');
    int bus = 0;
    int address = 0;
    char trailing = 0;
    if (colon == std::string::npos ||
        std::sscanf(uri.target.c_str(), "%d:%d%c", &bus, &address, &trailing) != 2 || bus < 1 || bus > 255 ||
        address < 1 || address > 127) {
      throw_error(ErrorCode::kInvalidArgument,
                  "USB device URI {}: the target '{}' must be BUS:ADDRESS (e.g. 1:4, as lsusb -s writes it)",
                  uri.to_string(), uri.target);
    }
    selector.bus = bus;
    selector.address = address;
  }
  for (const auto& [key, value] : uri.query) {
    if (key == "serial") selector.serial = value;
    else if (key == "vid") selector.vendor_id = parse_id(value, "vid");
    else if (key == "pid") selector.product_id = parse_id(value, "pid");
    else throw_error(ErrorCode::kInvalidArgument, "USB device URI {}: unknown key '{}' (serial, vid, pid)", uri.to_string(), key);
  }
  return selector;
}

std::vector<UsbDeviceInfo> list_usb_devices(std::uint16_t vendor_id, std::uint16_t product_id) {
  Context context;
  DeviceList devices(context.get());
  std::vector<UsbDeviceInfo> found;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(devices[i], &descriptor) != 0) continue;
    if (!ids_match(descriptor, vendor_id, product_id)) continue;
    libusb_device_handle* handle = nullptr;
    if (libusb_open(devices[i], &handle) != 0) handle = nullptr;  // listed without strings
    found.push_back(describe_device(devices[i], descriptor, handle));
    if (handle != nullptr) libusb_close(handle);
  }
  return found;
}

std::chrono::milliseconds UsbRetryPolicy::attempt_timeout() const {
  return std::max(std::chrono::milliseconds{1}, command_timeout / std::max(1, attempts));
}

struct UsbConnection::Impl {
  libusb_context* context = nullptr;
  libusb_device_handle* handle = nullptr;
  int interface_number = 0;
  UsbDeviceInfo info;
  std::string name;
  std::map<std::uint8_t, std::uint8_t> endpoint_types;  // address -> LIBUSB_TRANSFER_TYPE_*

  ~Impl() {
    if (handle != nullptr) {
      libusb_release_interface(handle, interface_number);
      libusb_close(handle);
    }
    if (context != nullptr) libusb_exit(context);
  }

  TransferResult transfer(std::uint8_t endpoint, std::uint8_t* data, std::size_t size,
                          std::chrono::milliseconds timeout) const {
    const auto type = endpoint_types.find(endpoint);
    if (type == endpoint_types.end()) {
      throw_error(ErrorCode::kInternal, "{}: endpoint 0x{:02x} is not on interface {}", name, endpoint,
                  interface_number);
    }
    int transferred = 0;
    const int length = static_cast<int>(size);
    const int result = type->second == LIBUSB_TRANSFER_TYPE_INTERRUPT
                           ? libusb_interrupt_transfer(handle, endpoint, data, length, &transferred, timeout_ms(timeout))
                           : libusb_bulk_transfer(handle, endpoint, data, length, &transferred, timeout_ms(timeout));
    TransferResult out;
    out.status = status_of(result);
    out.transferred = static_cast<std::size_t>(std::max(0, transferred));
    if (result != 0) out.error = libusb_error_name(result);
    return out;
  }
};

UsbConnection::UsbConnection(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
UsbConnection::~UsbConnection() = default;

std::unique_ptr<UsbConnection> UsbConnection::open(const UsbSelector& selector, int interface_number,
                                                   const std::string& kind) {
  auto impl = std::make_unique<Impl>();
  Context context;
  {
    DeviceList devices(context.get());
    for (std::size_t i = 0; i < devices.size() && impl->handle == nullptr; ++i) {
      libusb_device* device = devices[i];
      libusb_device_descriptor descriptor{};
      if (libusb_get_device_descriptor(device, &descriptor) != 0) continue;
      if (!ids_match(descriptor, selector.vendor_id, selector.product_id)) continue;
      if (selector.bus != 0 && libusb_get_bus_number(device) != selector.bus) continue;
      if (selector.address != 0 && libusb_get_device_address(device) != selector.address) continue;
      libusb_device_handle* handle = nullptr;
      const int opened = libusb_open(device, &handle);
      if (opened != 0) {
        if (!selector.serial.empty()) continue;  // cannot tell whether it is the one asked for
        throw_error(ErrorCode::kDevice, "{} {:04x}:{:04x} on bus {} address {}: cannot open it: {}", kind,
                    descriptor.idVendor, descriptor.idProduct, libusb_get_bus_number(device),
                    libusb_get_device_address(device), libusb_error_name(opened));
      }
      UsbDeviceInfo info = describe_device(device, descriptor, handle);
      if (!selector.serial.empty() && info.serial != selector.serial) {
        libusb_close(handle);
        continue;
      }
      impl->handle = handle;
      impl->info = std::move(info);
    }
  }
  if (impl->handle == nullptr) {
    throw_error(ErrorCode::kNotFound, "no {} found ({})", kind, selector.describe());
  }
  impl->context = context.release();
  impl->interface_number = interface_number;
  const UsbDeviceInfo& info = impl->info;
  impl->name = fmt::format("{} {:04x}:{:04x} on bus {} address {}", kind, info.vendor_id, info.product_id, info.bus,
                           info.address);
  if (!info.serial.empty()) impl->name += fmt::format(" (serial {})", info.serial);

  // Where a kernel driver (usbhid for the DLPC350) holds the interface, libusb detaches it
  // on claim and re-attaches it on release; not supported everywhere, which is fine.
  libusb_set_auto_detach_kernel_driver(impl->handle, 1);
  const int claimed = libusb_claim_interface(impl->handle, interface_number);
  if (claimed != 0) {
    throw_error(ErrorCode::kDevice, "{}: cannot claim interface {}: {} (is another program using it?)", impl->name,
                interface_number, libusb_error_name(claimed));
  }
  libusb_config_descriptor* config = nullptr;
  const int described = libusb_get_active_config_descriptor(libusb_get_device(impl->handle), &config);
  if (described != 0) {
    throw_error(ErrorCode::kDevice, "{}: cannot read its configuration descriptor: {}", impl->name,
                libusb_error_name(described));
  }
  for (int i = 0; i < config->bNumInterfaces; ++i) {
    const libusb_interface& interface = config->interface[i];
    if (interface.num_altsetting < 1 || interface.altsetting[0].bInterfaceNumber != interface_number) continue;
    const libusb_interface_descriptor& setting = interface.altsetting[0];
    for (int e = 0; e < setting.bNumEndpoints; ++e) {
      const libusb_endpoint_descriptor& endpoint = setting.endpoint[e];
      impl->endpoint_types[endpoint.bEndpointAddress] =
          static_cast<std::uint8_t>(endpoint.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK);
    }
  }
  libusb_free_config_descriptor(config);
  if (impl->endpoint_types.empty()) {
    throw_error(ErrorCode::kDevice, "{}: interface {} has no endpoints", impl->name, interface_number);
  }
  return std::unique_ptr<UsbConnection>(new UsbConnection(std::move(impl)));
}

const UsbDeviceInfo& UsbConnection::info() const { return impl_->info; }
const std::string& UsbConnection::name() const { return impl_->name; }

TransferResult UsbConnection::write(std::uint8_t endpoint, const std::uint8_t* data, std::size_t size,
                                    std::chrono::milliseconds timeout) {
  // libusb takes a non-const buffer for both directions; it does not modify an OUT buffer.
  std::vector<std::uint8_t> copy(data, data + size);
  TransferResult result = impl_->transfer(endpoint, copy.data(), copy.size(), timeout);
  if (result.status == TransferStatus::kOk && result.transferred != size) {
    result.status = TransferStatus::kError;
    result.error = fmt::format("short write ({} of {} bytes)", result.transferred, size);
  }
  return result;
}

TransferResult UsbConnection::read(std::uint8_t endpoint, std::uint8_t* data, std::size_t capacity,
                                   std::chrono::milliseconds timeout) {
  return impl_->transfer(endpoint, data, capacity, timeout);
}

bool UsbConnection::clear_halt(std::uint8_t endpoint) { return libusb_clear_halt(impl_->handle, endpoint) == 0; }

bool UsbConnection::transfer_failed(const TransferResult& result, std::uint8_t endpoint,
                                    std::chrono::milliseconds attempt_timeout, const std::string& during,
                                    ErrorCode* failure, std::string* problem) {
  switch (result.status) {
    case TransferStatus::kOk:
      return false;
    case TransferStatus::kTimeout:
      *failure = ErrorCode::kTimeout;
      *problem = fmt::format("endpoint 0x{:02x} {} within {} ms", endpoint,
                             (endpoint & 0x80) != 0 ? "gave no reply" : "took no data", attempt_timeout.count());
      return true;
    case TransferStatus::kStall:
      *failure = ErrorCode::kDevice;
      *problem = fmt::format("endpoint 0x{:02x} stalled ({})", endpoint, result.error);
      clear_halt(endpoint);
      return true;
    case TransferStatus::kNoDevice:
      throw_error(ErrorCode::kDevice, "{}: disconnected during {}", name(), during);
    case TransferStatus::kError:
      *failure = ErrorCode::kDevice;
      *problem = fmt::format("transfer on endpoint 0x{:02x} failed: {}", endpoint, result.error);
      return true;
  }
  return true;
}

}  // namespace sls::drivers::usb
