#include "drivers/aravis/aravis_camera.h"

#include <arpa/inet.h>
#include <arv.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <mutex>
#include <utility>

#include <fmt/format.h>

#include "drivers/aravis/aravis_support.h"
#include "drivers/aravis/frame_data.h"
#include "sdk/core/error.h"
#include "sdk/core/log.h"

namespace sls::drivers {
namespace {

using aravis_support::aravis_system_mutex;
using aravis_support::discover_locked;
using aravis_support::error_code_for;
using aravis_support::GErrorSlot;
using aravis_support::GFreeDeleter;
using aravis_support::join;
using aravis_support::take_string_array;
using aravis_support::text_or_empty;

bool is_ipv4_address(const std::string& text) {
  in_addr address{};
  return inet_pton(AF_INET, text.c_str(), &address) == 1;
}

// The MTU of the host interface holding IPv4 `address`; 0 when it cannot be told.
int interface_mtu(const in_addr& address) {
  ifaddrs* interfaces = nullptr;
  if (getifaddrs(&interfaces) != 0) return 0;
  std::string name;
  for (const ifaddrs* it = interfaces; it != nullptr; it = it->ifa_next) {
    if (it->ifa_addr == nullptr || it->ifa_addr->sa_family != AF_INET) continue;
    sockaddr_in candidate{};
    std::memcpy(&candidate, it->ifa_addr, sizeof candidate);  // memcpy: sockaddr is less aligned
    if (candidate.sin_addr.s_addr == address.s_addr) {
      name = it->ifa_name;
      break;
    }
  }
  freeifaddrs(interfaces);
  if (name.empty() || name.size() >= IFNAMSIZ) return 0;
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) return 0;
  ifreq request{};
  std::memcpy(request.ifr_name, name.c_str(), name.size() + 1);
  const int mtu = ioctl(fd, SIOCGIFMTU, &request) == 0 ? request.ifr_mtu : 0;
  close(fd);
  return mtu;
}

std::string describe_buffer_status(ArvBufferStatus status) {
  switch (status) {
    case ARV_BUFFER_STATUS_SUCCESS:
      return "success";
    case ARV_BUFFER_STATUS_CLEARED:
      return "CLEARED (the buffer was never filled)";
    case ARV_BUFFER_STATUS_TIMEOUT:
      return "TIMEOUT (not all packets arrived within the frame-retention time; resend did not recover them)";
    case ARV_BUFFER_STATUS_MISSING_PACKETS:
      return "MISSING_PACKETS (packets lost on the way and not resent)";
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID:
      return "WRONG_PACKET_ID (packets out of sequence)";
    case ARV_BUFFER_STATUS_SIZE_MISMATCH:
      return "SIZE_MISMATCH (the image did not fit the buffer)";
    case ARV_BUFFER_STATUS_FILLING:
      return "FILLING (the frame was still being received)";
    case ARV_BUFFER_STATUS_ABORTED:
      return "ABORTED (acquisition stopped while the frame was received)";
    case ARV_BUFFER_STATUS_UNKNOWN:
    default:
      return fmt::format("unknown status {}", static_cast<int>(status));
  }
}

}  // namespace

struct AravisCamera::Impl {
  ArvCamera* camera = nullptr;  // owned
  ArvDevice* device = nullptr;  // owned by `camera`
  ArvStream* stream = nullptr;  // owned; exists between start() and stop()
  std::atomic<bool> control_lost{false};
  mutable bool unresponsive = false;  // a command timed out

  DiscoveredCamera identity;
  std::string uri;
  std::string name;  // how messages name the camera
  // `name` as the heartbeat thread may read it: that thread runs from arv_camera_new() on,
  // before `name` is written, and only GLib's signal lock (a futex, invisible to
  // ThreadSanitizer, which reported the read in on_control_lost as a race) ordered the write
  // before the read. Published with release once written; read with acquire.
  std::atomic<const std::string*> heartbeat_name{nullptr};
  AravisCameraOptions options;
  const MonoLayout* layout = nullptr;
  ArvPixelFormat pixel_format = 0;
  std::string exposure_feature;
  std::string gain_feature;
  TriggerSource trigger_source = TriggerSource::kSoftware;
  int width = 0;
  int height = 0;
  int packet_size = 0;

  bool acquiring = false;
  bool have_last_frame_id = false;
  std::uint64_t last_frame_id = 0;
  AravisStatistics statistics;
  // The packet counters of the streams stop() already dropped (each start() makes a new one,
  // whose counters begin at 0), and the output queue as the last wait_image() left it.
  TransportStatistics transport_before;
  std::uint64_t output_queue_depth = 0;

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    // Stop quietly (the camera may be gone); the stream and the device's heartbeat threads end
    // in their finalizers, before this object's members (control_lost) are destroyed.
    if (acquiring && !unresponsive && !control_lost.load()) {
      GErrorSlot ignored;
      arv_camera_stop_acquisition(camera, ignored.out());
    }
    if (stream != nullptr) g_object_unref(stream);
    if (camera != nullptr) g_object_unref(camera);
  }

  // The current stream's packet counters (GigE Vision only; 0 without a stream).
  TransportStatistics stream_packets() const {
    TransportStatistics packets;
    if (stream == nullptr || !ARV_IS_GV_STREAM(stream)) return packets;
    guint64 resent = 0;
    guint64 missing = 0;
    arv_gv_stream_get_statistics(ARV_GV_STREAM(stream), &resent, &missing);
    packets.resent_packets = resent;
    packets.missing_packets = missing;
    return packets;
  }

  static void on_control_lost(ArvDevice* /*device*/, gpointer user) {
    // Runs on Aravis's heartbeat thread: only flag it; the next call reports it.
    auto* impl = static_cast<Impl*>(user);
    if (impl->control_lost.exchange(true)) return;
    const std::string* name = impl->heartbeat_name.load(std::memory_order_acquire);
    logger().warn("{}: control connection lost", name != nullptr ? *name : std::string("camera"));
  }

  void ensure_connected() const {
    if (control_lost.load()) {
      throw_error(ErrorCode::kDevice, "{} is gone: it stopped answering the control channel (heartbeat lost)", name);
    }
  }

  // Throws the Aravis error in `slot`, if any, as "<camera>: <action>: <Aravis message>". A
  // command that timed out marks the camera unresponsive, so that closing it does not wait for
  // more timeouts.
  void check(const GErrorSlot& slot, const std::string& action) const {
    if (!slot.failed()) return;
    const ErrorCode code = error_code_for(*slot.get());
    if (code == ErrorCode::kTimeout) unresponsive = true;
    throw Error(code, fmt::format("{}: {}: {}", name, action, text_or_empty(slot.get()->message)));
  }

  bool feature_available(const char* feature) const {
    if (arv_device_get_feature(device, feature) == nullptr) return false;
    GErrorSlot error;
    const gboolean available = arv_device_is_feature_available(device, feature, error.out());
    return !error.failed() && available != FALSE;
  }

  bool numeric_feature(const char* feature) const {
    ArvGcNode* node = arv_device_get_feature(device, feature);
    return node != nullptr && (ARV_IS_GC_FLOAT(node) || ARV_IS_GC_INTEGER(node));
  }

  // The first of `candidates` the camera has as a number feature; "" when none.
  std::string pick_feature(std::initializer_list<const char*> candidates) const {
    for (const char* candidate : candidates) {
      if (numeric_feature(candidate) && feature_available(candidate)) return candidate;
    }
    return {};
  }

  void write_number(const std::string& feature, double value) {
    ensure_connected();
    ArvGcNode* node = arv_device_get_feature(device, feature.c_str());
    GErrorSlot error;
    if (node != nullptr && ARV_IS_GC_FLOAT(node)) {
      double min = 0.0;
      double max = 0.0;
      arv_device_get_float_feature_bounds(device, feature.c_str(), &min, &max, error.out());
      check(error, "bounds of " + feature);
      if (!(value >= min && value <= max)) {
        throw_error(ErrorCode::kInvalidArgument, "{}: {} = {} is outside [{}, {}]", name, feature, value, min, max);
      }
      arv_device_set_float_feature_value(device, feature.c_str(), value, error.out());
    } else {
      gint64 min = 0;
      gint64 max = 0;
      arv_device_get_integer_feature_bounds(device, feature.c_str(), &min, &max, error.out());
      check(error, "bounds of " + feature);
      const double rounded = std::round(value);
      if (!(rounded >= static_cast<double>(min) && rounded <= static_cast<double>(max))) {
        throw_error(ErrorCode::kInvalidArgument, "{}: {} = {} is outside [{}, {}]", name, feature, value, min, max);
      }
      arv_device_set_integer_feature_value(device, feature.c_str(), static_cast<gint64>(rounded), error.out());
    }
    check(error, fmt::format("set {} = {}", feature, value));
  }

  double read_number(const std::string& feature) const {
    ensure_connected();
    ArvGcNode* node = arv_device_get_feature(device, feature.c_str());
    GErrorSlot error;
    double value = 0.0;
    if (node != nullptr && ARV_IS_GC_FLOAT(node)) {
      value = arv_device_get_float_feature_value(device, feature.c_str(), error.out());
    } else {
      value = static_cast<double>(arv_device_get_integer_feature_value(device, feature.c_str(), error.out()));
    }
    check(error, "read " + feature);
    return value;
  }

  void set_string_feature(const char* feature, const char* value) {
    GErrorSlot error;
    arv_device_set_string_feature_value(device, feature, value, error.out());
    check(error, fmt::format("set {} = {}", feature, value));
  }

  // Structured light needs fixed exposure and gain: switch the cameras' automatics off.
  void disable_automatics() {
    for (const char* feature : {"ExposureAuto", "GainAuto"}) {
      if (!feature_available(feature)) continue;
      GErrorSlot error;
      const gboolean has_off = arv_device_is_enumeration_entry_available(device, feature, "Off", error.out());
      if (!error.failed() && has_off != FALSE) set_string_feature(feature, "Off");
    }
  }

  void configure_pixel_format() {
    GErrorSlot error;
    guint count = 0;
    const char** formats = arv_camera_dup_available_pixel_formats_as_strings(camera, &count, error.out());
    const std::vector<std::string> offered = take_string_array(formats, count);
    check(error, "list pixel formats");
    if (std::find(offered.begin(), offered.end(), options.pixel_format) == offered.end()) {
      throw_error(ErrorCode::kUnsupported, "{} offers no pixel format {} (it offers: {})", name,
                  options.pixel_format, join(offered));
    }
    arv_camera_set_pixel_format_from_string(camera, options.pixel_format.c_str(), error.out());
    check(error, "set PixelFormat = " + options.pixel_format);
    pixel_format = arv_camera_get_pixel_format(camera, error.out());
    check(error, "read PixelFormat");
  }

  void configure_region() {
    GErrorSlot error;
    if (options.width > 0 || options.height > 0) {
      gint x = 0;
      gint y = 0;
      gint current_width = 0;
      gint current_height = 0;
      arv_camera_get_region(camera, &x, &y, &current_width, &current_height, error.out());
      check(error, "read the region");
      const int wanted_width = options.width > 0 ? options.width : current_width;
      const int wanted_height = options.height > 0 ? options.height : current_height;
      gint min_width = 0;
      gint max_width = 0;
      gint min_height = 0;
      gint max_height = 0;
      arv_camera_get_width_bounds(camera, &min_width, &max_width, error.out());
      check(error, "read the Width bounds");
      arv_camera_get_height_bounds(camera, &min_height, &max_height, error.out());
      check(error, "read the Height bounds");
      if (wanted_width < min_width || wanted_width > max_width || wanted_height < min_height ||
          wanted_height > max_height) {
        throw_error(ErrorCode::kInvalidArgument, "{}: image {}x{} is outside {}..{} x {}..{}", name, wanted_width,
                    wanted_height, min_width, max_width, min_height, max_height);
      }
      arv_camera_set_region(camera, 0, 0, wanted_width, wanted_height, error.out());
      check(error, fmt::format("set the region to {}x{}", wanted_width, wanted_height));
    }
    gint x = 0;
    gint y = 0;
    arv_camera_get_region(camera, &x, &y, &width, &height, error.out());
    check(error, "read the region");
  }

  // GigE Vision: the stream packet size. See AravisCameraOptions::packet_size.
  void negotiate_packet_size() {
    if (!arv_camera_is_gv_device(camera)) return;
    GErrorSlot error;
    gint64 min = 0;
    gint64 max = 0;
    arv_device_get_integer_feature_bounds(device, "GevSCPSPacketSize", &min, &max, error.out());
    check(error, "read the GevSCPSPacketSize bounds");
    gint64 increment = arv_device_get_integer_feature_increment(device, "GevSCPSPacketSize", error.out());
    if (error.failed() || increment < 1) increment = 1;

    gint64 wanted = options.packet_size;
    if (wanted > 0) {
      if (wanted < min || wanted > max) {
        throw_error(ErrorCode::kInvalidArgument, "{}: packet size {} is outside the camera's {}..{} bytes", name,
                    wanted, min, max);
      }
    } else if (feature_available("GevSCPSFireTestPacket")) {
      // The camera can fire test packets: Aravis finds the largest size that gets through.
      arv_camera_gv_auto_packet_size(camera, error.out());
      check(error, "negotiate the packet size");
      wanted = 0;
    } else {
      // No test packets: the largest size the camera allows that fits the host interface's MTU
      // (the packet size counts the IP and UDP headers, so it may equal the MTU).
      GSocketAddress* interface_address = arv_gv_device_get_interface_address(ARV_GV_DEVICE(device));
      sockaddr_in native{};
      int mtu = 0;
      GErrorSlot native_error;
      if (interface_address != nullptr &&
          g_socket_address_to_native(interface_address, &native, sizeof native, native_error.out()) != FALSE) {
        mtu = interface_mtu(native.sin_addr);
      }
      constexpr int kEthernetMtu = 1500;  // the safe assumption when the interface is unknown
      wanted = std::min<gint64>(max, mtu > 0 ? mtu : kEthernetMtu);
      wanted = min + (wanted - min) / increment * increment;
    }
    if (wanted > 0) {
      arv_camera_gv_set_packet_size(camera, static_cast<gint>(wanted), error.out());
      check(error, fmt::format("set GevSCPSPacketSize = {}", wanted));
    }
    packet_size = static_cast<int>(arv_camera_gv_get_packet_size(camera, error.out()));
    check(error, "read GevSCPSPacketSize");
  }

  void apply_trigger(TriggerSource source, const std::string& line) {
    ensure_connected();
    const std::string wanted = source == TriggerSource::kSoftware ? std::string("Software") : line;
    GErrorSlot error;
    guint count = 0;
    const char** names = arv_camera_dup_available_trigger_sources(camera, &count, error.out());
    const std::vector<std::string> sources = take_string_array(names, count);
    if (error.failed() || sources.empty()) {
      throw_error(ErrorCode::kUnsupported, "{} has no TriggerSource feature: it cannot be triggered", name);
    }
    if (std::find(sources.begin(), sources.end(), wanted) == sources.end()) {
      throw_error(ErrorCode::kUnsupported, "{} has no trigger source {} (it has: {})", name, wanted, join(sources));
    }
    // FrameStart: TriggerMode On with this source (other selectors Off, RisingEdge when offered).
    arv_camera_set_trigger(camera, wanted.c_str(), error.out());
    check(error, "set the trigger to " + wanted);
    trigger_source = source;
  }

  void configure() {
    disable_automatics();
    exposure_feature = pick_feature({"ExposureTime", "ExposureTimeAbs"});
    gain_feature = pick_feature({"Gain", "GainRaw"});
    configure_pixel_format();
    configure_region();
    GErrorSlot error;
    arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, error.out());
    check(error, "set AcquisitionMode = Continuous");
    apply_trigger(TriggerSource::kSoftware, options.trigger_line);
    negotiate_packet_size();
  }

  // `memory`: where the image goes (drivers::Camera::set_image_memory).
  CapturedImage convert(ArvBuffer* buffer, MemoryType memory) {
    CapturedImage captured;
    captured.frame_id = arv_buffer_get_frame_id(buffer);
    captured.timestamp_ns = static_cast<std::int64_t>(arv_buffer_get_timestamp(buffer));
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    if (status != ARV_BUFFER_STATUS_SUCCESS && have_last_frame_id) {
      // A buffer the transport could not complete may carry an id that is not its own (seen
      // under load with packet loss: 65433 between 65440 and 65442). Taken at face value it
      // invents lost frames and shifts the sequencer's trigger count; count it as the frame
      // after the last one instead (a real gap shows at the next whole frame).
      last_frame_id = next_frame_id(last_frame_id);
    } else {
      if (have_last_frame_id) captured.frames_missed = frames_missed_between(last_frame_id, captured.frame_id);
      have_last_frame_id = true;
      last_frame_id = captured.frame_id;
    }
    statistics.images++;
    statistics.frames_missed += captured.frames_missed;

    const auto incomplete = [&](const std::string& why) {
      captured.complete = false;
      captured.problem = fmt::format("{}: frame {} is not whole: {}", name, captured.frame_id, why);
      captured.image = Image16u();
      statistics.incomplete_images++;
      return captured;
    };
    // Read nothing of the image before the status says it is whole: a failed buffer's data
    // holds whatever packets arrived over the previous frame's pixels.
    if (status != ARV_BUFFER_STATUS_SUCCESS) return incomplete("transport status " + describe_buffer_status(status));
    const ArvBufferPayloadType payload_type = arv_buffer_get_payload_type(buffer);
    if (payload_type != ARV_BUFFER_PAYLOAD_TYPE_IMAGE && payload_type != ARV_BUFFER_PAYLOAD_TYPE_EXTENDED_CHUNK_DATA) {
      return incomplete(fmt::format("payload type {} is no image", static_cast<int>(payload_type)));
    }
    const ArvPixelFormat format = arv_buffer_get_image_pixel_format(buffer);
    if (format != pixel_format) {
      return incomplete(fmt::format("pixel format 0x{:08x}, not the configured {}", format, layout->name));
    }
    const int image_width = arv_buffer_get_image_width(buffer);
    const int image_height = arv_buffer_get_image_height(buffer);
    gint padding_x = 0;
    gint padding_y = 0;
    arv_buffer_get_image_padding(buffer, &padding_x, &padding_y);
    std::size_t size = 0;
    const auto* data = static_cast<const std::uint8_t*>(arv_buffer_get_image_data(buffer, &size));
    if (data == nullptr || image_width <= 0 || image_height <= 0 || padding_x < 0) {
      return incomplete(fmt::format("no image data ({}x{}, {} bytes)", image_width, image_height, size));
    }
    const std::size_t row_stride =
        static_cast<std::size_t>(image_width) * static_cast<std::size_t>(layout->bytes_per_pixel) +
        static_cast<std::size_t>(padding_x);
    try {
      captured.image = Image16u(memory);  // the one copy out of Aravis's buffer lands where the scan reads
      unpack_mono(data, size, image_width, image_height, row_stride, layout->bytes_per_pixel, captured.image);
    } catch (const Error& error) {
      return incomplete(error.what());
    }
    return captured;
  }
};

AravisCamera::AravisCamera(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
AravisCamera::~AravisCamera() = default;

std::unique_ptr<AravisCamera> AravisCamera::open(const std::string& id_or_address, const AravisCameraOptions& options) {
  const MonoLayout* layout = find_mono_layout(options.pixel_format);
  if (layout == nullptr) {
    throw_error(ErrorCode::kUnsupported, "pixel format '{}': the Aravis driver reads Mono8, Mono10, Mono12, Mono16",
                options.pixel_format);
  }
  if (options.width < 0 || options.height < 0 || options.packet_size < 0 || options.buffer_count < 1 ||
      options.buffer_count > 1024) {
    throw_error(ErrorCode::kInvalidArgument,
                "camera options: width {}, height {}, packet size {} must be >= 0 and buffers {} in 1..1024",
                options.width, options.height, options.packet_size, options.buffer_count);
  }
  if (id_or_address.empty()) throw_error(ErrorCode::kInvalidArgument, "no camera id or address given");

  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->layout = layout;
  {
    std::lock_guard<std::mutex> lock(aravis_system_mutex());
    std::string open_name = id_or_address;
    if (!is_ipv4_address(id_or_address)) {
      const std::vector<DiscoveredCamera> cameras = discover_locked();
      const auto match = std::find_if(cameras.begin(), cameras.end(), [&](const DiscoveredCamera& camera) {
        return camera.id == id_or_address || camera.serial == id_or_address;
      });
      if (match == cameras.end()) {
        std::vector<std::string> seen;
        for (const DiscoveredCamera& camera : cameras) seen.push_back(camera.id);
        throw_error(ErrorCode::kNotFound, "no camera with id or serial '{}' answers discovery (found: {})",
                    id_or_address, join(seen));
      }
      // By address for GigE Vision: opening by id can bind the stream to another interface.
      open_name = match->protocol == "GigEVision" && !match->address.empty() ? match->address : match->id;
      impl->identity = *match;
    }
    GErrorSlot error;
    impl->camera = arv_camera_new(open_name.c_str(), error.out());
    if (error.failed() || impl->camera == nullptr) {
      const ErrorCode code = error.failed() ? error_code_for(*error.get()) : ErrorCode::kNotFound;
      throw Error(code == ErrorCode::kDevice ? ErrorCode::kNotFound : code,
                  fmt::format("no GenICam camera could be opened at '{}': {}", open_name,
                              error.failed() ? text_or_empty(error.get()->message) : std::string("no answer")));
    }
  }
  Impl& camera = *impl;
  camera.device = arv_camera_get_device(camera.camera);
  GErrorSlot error;
  DiscoveredCamera& identity = camera.identity;
  identity.id = text_or_empty(arv_camera_get_device_id(camera.camera, error.out()));
  identity.vendor = text_or_empty(arv_camera_get_vendor_name(camera.camera, error.out()));
  identity.model = text_or_empty(arv_camera_get_model_name(camera.camera, error.out()));
  identity.serial = text_or_empty(arv_camera_get_device_serial_number(camera.camera, error.out()));
  if (arv_camera_is_gv_device(camera.camera)) {
    identity.protocol = "GigEVision";
    GSocketAddress* address = arv_gv_device_get_device_address(ARV_GV_DEVICE(camera.device));
    if (address != nullptr && G_IS_INET_SOCKET_ADDRESS(address)) {
      std::unique_ptr<gchar, GFreeDeleter> text(
          g_inet_address_to_string(g_inet_socket_address_get_address(G_INET_SOCKET_ADDRESS(address))));
      identity.address = text_or_empty(text.get());
    }
  } else if (arv_camera_is_uv_device(camera.camera)) {
    identity.protocol = "USB3Vision";
  }
  camera.uri = identity.uri();
  camera.name = fmt::format("camera {} {} '{}' ({})", identity.vendor, identity.model, identity.serial, camera.uri);
  camera.heartbeat_name.store(&camera.name, std::memory_order_release);
  g_signal_connect(camera.device, "control-lost", G_CALLBACK(&Impl::on_control_lost), &camera);
  camera.configure();
  return std::unique_ptr<AravisCamera>(new AravisCamera(std::move(impl)));
}

std::unique_ptr<AravisCamera> AravisCamera::open(const DeviceUri& uri) {
  if (uri.scheme != "gige" && uri.scheme != "usb3") {
    throw_error(ErrorCode::kInvalidArgument, "'{}' is no camera URI (gige://address or usb3://serial)",
                uri.to_string());
  }
  static const char* const kKeys[] = {"format", "width", "height", "packet_size", "buffers", "trigger_line"};
  for (const auto& entry : uri.query) {
    if (std::find_if(std::begin(kKeys), std::end(kKeys), [&](const char* key) { return entry.first == key; }) ==
        std::end(kKeys)) {
      throw_error(ErrorCode::kInvalidArgument, "camera URI '{}': unknown key '{}' (known: {})", uri.to_string(),
                  entry.first, "format, width, height, packet_size, buffers, trigger_line");
    }
  }
  AravisCameraOptions options;
  options.pixel_format = uri.get("format", options.pixel_format);
  options.width = uri.get_int("width", options.width);
  options.height = uri.get_int("height", options.height);
  options.packet_size = uri.get_int("packet_size", options.packet_size);
  options.buffer_count = uri.get_int("buffers", options.buffer_count);
  options.trigger_line = uri.get("trigger_line", options.trigger_line);
  std::unique_ptr<AravisCamera> camera = open(uri.target, options);
  const std::string& protocol = camera->device().protocol;
  if ((uri.scheme == "gige") != (protocol == "GigEVision")) {
    throw_error(ErrorCode::kInvalidArgument, "camera URI '{}' names a {} camera", uri.to_string(), protocol);
  }
  return camera;
}

CameraInfo AravisCamera::info() const {
  return {impl_->uri, impl_->identity.vendor + " " + impl_->identity.model, impl_->identity.serial, impl_->width,
          impl_->height, impl_->layout->bit_depth};
}

void AravisCamera::set_exposure_us(double exposure_us) {
  if (impl_->exposure_feature.empty()) {
    throw_error(ErrorCode::kUnsupported, "{} has neither ExposureTime nor ExposureTimeAbs", impl_->name);
  }
  impl_->write_number(impl_->exposure_feature, exposure_us);
}

double AravisCamera::exposure_us() const {
  if (impl_->exposure_feature.empty()) {
    throw_error(ErrorCode::kUnsupported, "{} has neither ExposureTime nor ExposureTimeAbs", impl_->name);
  }
  return impl_->read_number(impl_->exposure_feature);
}

void AravisCamera::set_gain(double gain) {
  if (impl_->gain_feature.empty()) {
    throw_error(ErrorCode::kUnsupported, "{} has neither Gain nor GainRaw", impl_->name);
  }
  impl_->write_number(impl_->gain_feature, gain);
}

double AravisCamera::gain() const {
  if (impl_->gain_feature.empty()) {
    throw_error(ErrorCode::kUnsupported, "{} has neither Gain nor GainRaw", impl_->name);
  }
  return impl_->read_number(impl_->gain_feature);
}

void AravisCamera::set_trigger_source(TriggerSource source) { impl_->apply_trigger(source, impl_->options.trigger_line); }

void AravisCamera::set_trigger_line(const std::string& line) {
  if (impl_->trigger_source == TriggerSource::kHardwareLine) impl_->apply_trigger(TriggerSource::kHardwareLine, line);
  impl_->options.trigger_line = line;
}

void AravisCamera::start() {
  Impl& camera = *impl_;
  camera.ensure_connected();
  // Still acquiring (a capture that failed on this camera leaves it running): begin afresh, so
  // no image queued for the old triggers is taken for a new one.
  if (camera.acquiring) stop();
  GErrorSlot error;
  const guint payload = arv_camera_get_payload(camera.camera, error.out());
  camera.check(error, "read PayloadSize");
  ArvStream* stream = arv_camera_create_stream(camera.camera, nullptr, nullptr, error.out());
  if (error.failed() || stream == nullptr) {
    if (stream != nullptr) g_object_unref(stream);
    camera.check(error, "create the stream");
    throw_error(ErrorCode::kDevice, "{}: no stream could be created", camera.name);
  }
  // The pool: each buffer cycles camera → wait_image (copied out) → back to the stream.
  for (int i = 0; i < camera.options.buffer_count; ++i) arv_stream_push_buffer(stream, arv_buffer_new_allocate(payload));
  arv_camera_start_acquisition(camera.camera, error.out());
  if (error.failed()) {
    g_object_unref(stream);
    camera.check(error, "start the acquisition");
  }
  camera.stream = stream;
  camera.acquiring = true;
  camera.have_last_frame_id = false;
  camera.output_queue_depth = 0;
}

void AravisCamera::stop() {
  Impl& camera = *impl_;
  if (!camera.acquiring) return;
  GErrorSlot error;
  arv_camera_stop_acquisition(camera.camera, error.out());
  const TransportStatistics packets = camera.stream_packets();
  camera.transport_before.resent_packets += packets.resent_packets;
  camera.transport_before.missing_packets += packets.missing_packets;
  g_object_unref(camera.stream);  // drops the pool and any frame not yet taken
  camera.stream = nullptr;
  camera.acquiring = false;
  camera.ensure_connected();
  camera.check(error, "stop the acquisition");
}

void AravisCamera::software_trigger() {
  Impl& camera = *impl_;
  camera.ensure_connected();
  if (!camera.acquiring) throw_error(ErrorCode::kInvalidArgument, "{}: software trigger before start()", camera.name);
  if (camera.trigger_source != TriggerSource::kSoftware) {
    throw_error(ErrorCode::kInvalidArgument, "{} is triggered by {}: software_trigger() needs the software source",
                camera.name, camera.options.trigger_line);
  }
  GErrorSlot error;
  arv_camera_software_trigger(camera.camera, error.out());
  camera.check(error, "software trigger (TriggerSoftware)");
}

CapturedImage AravisCamera::wait_image(std::chrono::milliseconds timeout) {
  Impl& camera = *impl_;
  camera.ensure_connected();
  if (!camera.acquiring) throw_error(ErrorCode::kInvalidArgument, "{}: wait_image before start()", camera.name);
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline = Clock::now() + std::max(timeout, std::chrono::milliseconds(0));
  // Wait in slices so that a lost camera is reported soon, not only at the deadline.
  constexpr std::chrono::microseconds kSlice(100000);
  ArvBuffer* buffer = nullptr;
  while (buffer == nullptr) {
    const auto left = std::chrono::duration_cast<std::chrono::microseconds>(deadline - Clock::now());
    if (left.count() <= 0) break;
    buffer = arv_stream_timeout_pop_buffer(camera.stream, static_cast<guint64>(std::min(left, kSlice).count()));
    if (buffer == nullptr) camera.ensure_connected();
  }
  if (buffer == nullptr) {
    camera.ensure_connected();
    throw_error(ErrorCode::kTimeout, "{}: no image within {} ms", camera.name, timeout.count());
  }
  // The buffer goes back to the pool whatever happens while it is read.
  struct ReturnToPool {
    ArvStream* stream;
    ArvBuffer* buffer;
    ~ReturnToPool() { arv_stream_push_buffer(stream, buffer); }
  } give_back{camera.stream, buffer};
  gint waiting_input = 0;
  gint waiting_output = 0;
  arv_stream_get_n_buffers(camera.stream, &waiting_input, &waiting_output);
  camera.output_queue_depth = static_cast<std::uint64_t>(std::max(waiting_output, 0));
  return camera.convert(buffer, image_memory());
}

std::string AravisCamera::feature_value(const std::string& feature) const {
  impl_->ensure_connected();
  ArvGcNode* node = arv_device_get_feature(impl_->device, feature.c_str());
  if (node == nullptr || !ARV_IS_GC_FEATURE_NODE(node)) {
    throw_error(ErrorCode::kUnsupported, "{} has no feature {}", impl_->name, feature);
  }
  GErrorSlot error;
  const std::string value = text_or_empty(arv_gc_feature_node_get_value_as_string(ARV_GC_FEATURE_NODE(node), error.out()));
  impl_->check(error, "read " + feature);
  return value;
}

const std::string& AravisCamera::exposure_feature() const { return impl_->exposure_feature; }
const std::string& AravisCamera::gain_feature() const { return impl_->gain_feature; }
int AravisCamera::packet_size() const { return impl_->packet_size; }
const DiscoveredCamera& AravisCamera::device() const { return impl_->identity; }
AravisStatistics AravisCamera::statistics() const { return impl_->statistics; }

std::optional<TransportStatistics> AravisCamera::transport_statistics() const {
  const Impl& camera = *impl_;
  if (camera.identity.protocol != "GigEVision") return std::nullopt;
  TransportStatistics transport = camera.stream_packets();
  transport.resent_packets += camera.transport_before.resent_packets;
  transport.missing_packets += camera.transport_before.missing_packets;
  transport.output_queue_depth = camera.output_queue_depth;
  return transport;
}

}  // namespace sls::drivers
