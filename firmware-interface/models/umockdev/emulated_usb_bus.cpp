#include "firmware-interface/models/umockdev/emulated_usb_bus.h"

#include <endian.h>
#include <linux/usb/ch9.h>
#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <mutex>
#include <vector>

#include "sdk/core/error.h"

namespace sls::fwif::models {
namespace {

// ---- descriptors ------------------------------------------------------------------------
void put16(std::vector<std::uint8_t>& out, std::uint16_t value) {
  out.push_back(static_cast<std::uint8_t>(value & 0xFF));
  out.push_back(static_cast<std::uint8_t>(value >> 8));
}

std::vector<std::uint8_t> device_descriptor(const UsbIdentity& id) {
  std::vector<std::uint8_t> d = {18, USB_DT_DEVICE};
  put16(d, 0x0200);                  // bcdUSB 2.0
  d.insert(d.end(), {0, 0, 0, 64});  // class from the interface, max packet size of endpoint 0
  put16(d, id.vendor_id);
  put16(d, id.product_id);
  put16(d, id.device_release);
  d.insert(d.end(), {1, 2, 3, 1});  // string indices (manufacturer, product, serial), 1 configuration
  return d;
}

std::vector<std::uint8_t> configuration_descriptor(const UsbIdentity& id) {
  std::vector<std::uint8_t> body = {9, USB_DT_INTERFACE, 0, 0, static_cast<std::uint8_t>(id.endpoints.size()),
                                    id.interface_class, id.interface_subclass, id.interface_protocol, 0};
  if (id.interface_class == USB_CLASS_HID) {
    // HID class descriptor: HID 1.11, one report descriptor of 34 bytes (never fetched here).
    body.insert(body.end(), {9, 0x21, 0x11, 0x01, 0, 1, 0x22, 34, 0});
  }
  for (const EndpointDescription& ep : id.endpoints) {
    body.insert(body.end(), {7, USB_DT_ENDPOINT, ep.address, static_cast<std::uint8_t>(ep.type)});
    put16(body, ep.max_packet_size);
    body.push_back(ep.interval);
  }
  std::vector<std::uint8_t> d = {9, USB_DT_CONFIG};
  put16(d, static_cast<std::uint16_t>(9 + body.size()));
  d.insert(d.end(), {1, 1, 0, 0x80, 50});  // 1 interface, configuration 1, bus powered, 100 mA
  d.insert(d.end(), body.begin(), body.end());
  return d;
}

std::vector<std::uint8_t> string_descriptor(const UsbIdentity& id, int index) {
  if (index == 0) return {4, USB_DT_STRING, 0x09, 0x04};  // US English
  const std::string& text = index == 1 ? id.manufacturer : index == 2 ? id.product : id.serial;
  std::vector<std::uint8_t> d = {static_cast<std::uint8_t>(2 + 2 * text.size()), USB_DT_STRING};
  for (const char c : text) put16(d, static_cast<std::uint8_t>(c));
  return d;
}

std::string hex(const std::vector<std::uint8_t>& bytes) {
  std::string text;
  for (const std::uint8_t b : bytes) text += fmt::format("{:02x}", b);
  return text;
}

// ---- one emulated device ----------------------------------------------------------------
struct PendingUrb {
  UMockdevIoctlData* urb = nullptr;
  UMockdevIoctlData* buffer = nullptr;
};

struct DeviceSlot {
  std::shared_ptr<UsbFunction> device;
  UsbIdentity identity;
  std::vector<std::uint8_t> device_descriptor;
  std::vector<std::uint8_t> configuration_descriptor;
  std::string dev_path;
  UMockdevIoctlBase* handler = nullptr;
  std::mutex mutex;
  std::deque<PendingUrb> waiting;  // submitted, the device has not completed them yet
  std::deque<PendingUrb> done;     // completed, for the host to reap in order
  std::uint64_t ioctls = 0;
};

usbdevfs_urb* urb_of(const PendingUrb& pending) { return reinterpret_cast<usbdevfs_urb*>(pending.urb->data); }

void release(PendingUrb& pending) {
  g_object_unref(pending.buffer);
  g_object_unref(pending.urb);
}

// Answers a control transfer: the standard descriptor requests; everything else stalls.
void control_transfer(DeviceSlot& slot, usbdevfs_urb* urb, std::uint8_t* buffer) {
  usb_ctrlrequest setup;
  std::memcpy(&setup, buffer, sizeof setup);
  const std::uint16_t value = le16toh(setup.wValue);
  const std::uint16_t length = le16toh(setup.wLength);
  std::vector<std::uint8_t> reply;
  bool known = false;
  if (setup.bRequestType == (USB_DIR_IN | USB_TYPE_STANDARD | USB_RECIP_DEVICE) &&
      setup.bRequest == USB_REQ_GET_DESCRIPTOR) {
    const int type = value >> 8;
    const int index = value & 0xFF;
    known = true;
    if (type == USB_DT_DEVICE) reply = slot.device_descriptor;
    else if (type == USB_DT_CONFIG) reply = slot.configuration_descriptor;
    else if (type == USB_DT_STRING && index <= 3) reply = string_descriptor(slot.identity, index);
    else known = false;
  }
  if (!known) {
    urb->status = -EPIPE;
    urb->actual_length = 0;
    return;
  }
  const std::size_t count = std::min<std::size_t>(reply.size(), length);
  std::memcpy(buffer + sizeof setup, reply.data(), count);
  urb->status = 0;
  urb->actual_length = static_cast<int>(count);
}

// Offers a bulk or interrupt URB to the device; returns false while the device NAKs it.
bool offer(DeviceSlot& slot, const PendingUrb& pending) {
  usbdevfs_urb* urb = urb_of(pending);
  std::uint8_t* buffer = pending.buffer->data;
  const auto length = static_cast<std::size_t>(urb->buffer_length);
  TransferOutcome outcome;
  std::vector<std::uint8_t> in;
  if ((urb->endpoint & USB_DIR_IN) != 0) {
    outcome = slot.device->read(urb->endpoint, length, in);
  } else {
    outcome = slot.device->write(urb->endpoint, buffer, length);
  }
  switch (outcome) {
    case TransferOutcome::kPending: return false;
    case TransferOutcome::kDone:
      if ((urb->endpoint & USB_DIR_IN) != 0) {
        const std::size_t count = std::min(in.size(), length);
        std::memcpy(buffer, in.data(), count);
        urb->actual_length = static_cast<int>(count);
      } else {
        urb->actual_length = urb->buffer_length;
      }
      urb->status = 0;
      return true;
    case TransferOutcome::kStall:
      urb->status = -EPIPE;
      urb->actual_length = 0;
      return true;
    case TransferOutcome::kNoDevice:
      urb->status = -ENODEV;
      urb->actual_length = 0;
      return true;
  }
  return true;
}

// Completes the waiting URBs the device can answer now.
void pump(DeviceSlot& slot) {
  for (auto it = slot.waiting.begin(); it != slot.waiting.end();) {
    if (offer(slot, *it)) {
      slot.done.push_back(*it);
      it = slot.waiting.erase(it);
    } else {
      ++it;
    }
  }
}

void complete(UMockdevIoctlClient* client, long result, int error) {
  umockdev_ioctl_client_complete(client, result, error);
}

// usbdevfs requests arrive on umockdev's ioctl thread while the client blocks in ioctl().
gboolean on_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer user) {
  auto& slot = *static_cast<DeviceSlot*>(user);
  std::lock_guard<std::mutex> lock(slot.mutex);
  ++slot.ioctls;
  const gulong request = umockdev_ioctl_client_get_request(client);
  UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
  GError* error = nullptr;
  switch (request) {
    case USBDEVFS_GET_CAPABILITIES: {
      UMockdevIoctlData* data = umockdev_ioctl_data_resolve(arg, 0, sizeof(guint32), &error);
      const guint32 capabilities =
          USBDEVFS_CAP_ZERO_PACKET | USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM;
      std::memcpy(data->data, &capabilities, sizeof capabilities);
      g_object_unref(data);
      complete(client, 0, 0);
      return TRUE;
    }
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE:
    case USBDEVFS_RESET:
    case USBDEVFS_RESETEP:
    case USBDEVFS_SETINTERFACE:
    case USBDEVFS_SETCONFIGURATION:
      complete(client, 0, 0);
      return TRUE;
    case USBDEVFS_CLEAR_HALT: {
      UMockdevIoctlData* data = umockdev_ioctl_data_resolve(arg, 0, sizeof(unsigned int), &error);
      unsigned int endpoint = 0;
      std::memcpy(&endpoint, data->data, sizeof endpoint);
      g_object_unref(data);
      slot.device->clear_halt(static_cast<std::uint8_t>(endpoint));
      complete(client, 0, 0);
      return TRUE;
    }
    case USBDEVFS_DISCONNECT_CLAIM:  // libusb's auto-detach: no driver to disconnect, so a plain claim
      complete(client, 0, 0);
      return TRUE;
    case USBDEVFS_GETDRIVER:
    case USBDEVFS_IOCTL:             // driver (dis)connect requests: no kernel driver is bound
      complete(client, -1, ENODATA);
      return TRUE;
    case USBDEVFS_SUBMITURB: {
      UMockdevIoctlData* urb_data = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), &error);
      auto* urb = reinterpret_cast<usbdevfs_urb*>(urb_data->data);
      UMockdevIoctlData* buffer = umockdev_ioctl_data_resolve(urb_data, offsetof(usbdevfs_urb, buffer),
                                                              static_cast<gsize>(urb->buffer_length), &error);
      PendingUrb pending{urb_data, buffer};
      if (slot.device->behaviour() == Behaviour::kUnplugged) {
        release(pending);
        complete(client, -1, ENODEV);  // what usbdevfs says once the device is gone
        return TRUE;
      }
      if (urb->type == USBDEVFS_URB_TYPE_CONTROL) {
        control_transfer(slot, urb, buffer->data);
        slot.done.push_back(pending);
      } else {
        slot.waiting.push_back(pending);
        pump(slot);
      }
      complete(client, 0, 0);
      return TRUE;
    }
    case USBDEVFS_DISCARDURB: {
      gulong address = 0;
      std::memcpy(&address, arg->data, sizeof address);  // the argument is the client's URB pointer
      for (auto it = slot.waiting.begin(); it != slot.waiting.end(); ++it) {
        if (it->urb->client_addr == address) {
          urb_of(*it)->status = -ENOENT;
          urb_of(*it)->actual_length = 0;
          slot.done.push_back(*it);
          slot.waiting.erase(it);
          complete(client, 0, 0);
          return TRUE;
        }
      }
      complete(client, -1, EINVAL);
      return TRUE;
    }
    case USBDEVFS_REAPURB:
    case USBDEVFS_REAPURBNDELAY: {
      pump(slot);
      if (slot.done.empty()) {
        complete(client, -1, EAGAIN);
        return TRUE;
      }
      PendingUrb pending = slot.done.front();
      slot.done.pop_front();
      UMockdevIoctlData* out = umockdev_ioctl_data_resolve(arg, 0, sizeof(gpointer), &error);
      umockdev_ioctl_data_set_ptr(out, 0, pending.urb);  // hand the client its own URB back
      complete(client, 0, 0);
      g_object_unref(out);
      release(pending);
      return TRUE;
    }
    default:
      std::fprintf(stderr, "[emulated usb %s] unhandled usbdevfs ioctl 0x%lx: ENOTTY\n", slot.dev_path.c_str(),
                   request);
      complete(client, -1, ENOTTY);
      return TRUE;
  }
}

}  // namespace

bool umockdev_preload_active() {
  const char* preload = std::getenv("LD_PRELOAD");
  return preload != nullptr && std::strstr(preload, "libumockdev-preload") != nullptr;
}

struct EmulatedUsbBus::Impl {
  UMockdevTestbed* testbed = nullptr;
  std::vector<std::unique_ptr<DeviceSlot>> slots;
};

EmulatedUsbBus::EmulatedUsbBus() : impl_(std::make_unique<Impl>()) {
  if (!umockdev_preload_active()) {
    throw_error(ErrorCode::kUnsupported,
                "emulated USB bus: libumockdev-preload is not loaded; run the program under umockdev-wrapper");
  }
  impl_->testbed = umockdev_testbed_new();  // points $UMOCKDEV_DIR at a fresh sysfs/dev tree
  if (!umockdev_in_mock_environment()) {   // only meaningful after testbed_new: its answer is cached
    g_object_unref(impl_->testbed);
    throw_error(ErrorCode::kUnsupported, "emulated USB bus: umockdev reports no mock environment");
  }
}

EmulatedUsbBus::~EmulatedUsbBus() {
  for (auto& slot : impl_->slots) {
    umockdev_testbed_detach_ioctl(impl_->testbed, slot->dev_path.c_str(), nullptr);
    g_object_unref(slot->handler);
    std::lock_guard<std::mutex> lock(slot->mutex);
    for (PendingUrb& pending : slot->waiting) release(pending);
    for (PendingUrb& pending : slot->done) release(pending);
  }
  g_object_unref(impl_->testbed);
}

void EmulatedUsbBus::plug(std::shared_ptr<UsbFunction> device, int bus, int address) {
  if (bus < 1 || bus > 255 || address < 1 || address > 127) {
    throw_error(ErrorCode::kInvalidArgument, "emulated USB bus: bus {} address {} out of range", bus, address);
  }
  auto slot = std::make_unique<DeviceSlot>();
  slot->identity = device->identity();
  slot->device = std::move(device);
  slot->device_descriptor = device_descriptor(slot->identity);
  slot->configuration_descriptor = configuration_descriptor(slot->identity);
  const UsbIdentity& id = slot->identity;
  const std::string node = fmt::format("bus/usb/{:03}/{:03}", bus, address);
  slot->dev_path = "/dev/" + node;
  // The udev database record umockdev reads: P (sysfs path), N (device node), E (properties),
  // A (sysfs attributes, values end with a newline), H (binary attributes as hex).
  const std::string record = fmt::format(
      "P: /devices/pci0000:00/0000:00:14.0/usb{bus}/{bus}-{address}\n"
      "N: {node}\n"
      "E: BUSNUM={bus:03}\nE: DEVNUM={address:03}\nE: DEVNAME=/dev/{node}\nE: DEVTYPE=usb_device\n"
      "E: DRIVER=usb\nE: PRODUCT={vid:x}/{pid:x}/{release:x}\nE: SUBSYSTEM=usb\nE: MAJOR=189\nE: MINOR={minor}\n"
      "A: busnum={bus}\nA: devnum={address}\nA: bConfigurationValue=1\nA: idVendor={vid:04x}\n"
      "A: idProduct={pid:04x}\nA: speed={speed}\nA: manufacturer={manufacturer}\nA: product={product}\n"
      "A: serial={serial}\nH: descriptors={descriptors}\n",
      fmt::arg("bus", bus), fmt::arg("address", address), fmt::arg("node", node), fmt::arg("vid", id.vendor_id),
      fmt::arg("pid", id.product_id), fmt::arg("release", id.device_release),
      fmt::arg("minor", (bus - 1) * 128 + address - 1), fmt::arg("speed", 480),
      fmt::arg("manufacturer", id.manufacturer), fmt::arg("product", id.product), fmt::arg("serial", id.serial),
      fmt::arg("descriptors", hex(slot->device_descriptor) + hex(slot->configuration_descriptor)));
  GError* error = nullptr;
  if (!umockdev_testbed_add_from_string(impl_->testbed, record.c_str(), &error)) {
    const std::string message = error != nullptr ? error->message : "unknown error";
    g_clear_error(&error);
    throw_error(ErrorCode::kInternal, "emulated USB bus: adding {}: {}", slot->dev_path, message);
  }
  slot->handler = umockdev_ioctl_base_new();
  g_signal_connect_data(slot->handler, "handle-ioctl", reinterpret_cast<GCallback>(&on_ioctl), slot.get(), nullptr,
                        GConnectFlags{});
  if (!umockdev_testbed_attach_ioctl(impl_->testbed, slot->dev_path.c_str(), slot->handler, &error)) {
    const std::string message = error != nullptr ? error->message : "unknown error";
    g_clear_error(&error);
    g_object_unref(slot->handler);
    throw_error(ErrorCode::kInternal, "emulated USB bus: attaching the ioctl handler to {}: {}", slot->dev_path,
                message);
  }
  impl_->slots.push_back(std::move(slot));
}

std::uint64_t EmulatedUsbBus::ioctl_count() const {
  std::uint64_t total = 0;
  for (const auto& slot : impl_->slots) {
    std::lock_guard<std::mutex> lock(slot->mutex);
    total += slot->ioctls;
  }
  return total;
}

}  // namespace sls::fwif::models
