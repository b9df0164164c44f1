#include "mfcd/hal/aravis_camera.hpp"

#include <arpa/inet.h>
#include <arv.h>
#include <syslog.h>

#include <algorithm>
#include <string>
#include <vector>

#include "g_owned.hpp"
#include "mfcd/hal/clock.hpp"
#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

namespace {

using CameraRef = GOwned<ArvCamera, g_object_unref>;
using StreamRef = GOwned<ArvStream, g_object_unref>;
using ErrorRef = GOwned<GError, g_error_free>;
using NameArray = GOwned<const char*, g_free>;  // Aravis's dup_*_as_strings: the array is ours, not the strings
using ValueArray = GOwned<gint64, g_free>;

// Aravis's heartbeat thread reports that the camera no longer acknowledges us as its controller
// (it stopped answering for the heartbeat timeout, or another host took it over).
void on_control_lost(ArvDevice*, gpointer flag) { static_cast<std::atomic<bool>*>(flag)->store(true); }

// Whether a GError says the camera stopped answering (as opposed to refusing a value).
bool is_gone_error(const GError* e) {
  return e->domain == ARV_DEVICE_ERROR &&
         (e->code == ARV_DEVICE_ERROR_TIMEOUT || e->code == ARV_DEVICE_ERROR_NOT_CONNECTED ||
          e->code == ARV_DEVICE_ERROR_TRANSFER_ERROR);
}

bool is_missing_feature_error(const GError* e) {
  return (e->domain == ARV_DEVICE_ERROR && e->code == ARV_DEVICE_ERROR_FEATURE_NOT_FOUND) ||
         (e->domain == ARV_GC_ERROR && e->code == ARV_GC_ERROR_NODE_NOT_FOUND);
}

std::string join(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "nothing" : s;
}

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

std::size_t bytes_per_source_pixel(SourceFormat f) { return f == SourceFormat::Grey ? 1 : 2; }

// GError → the HAL's error kinds, naming the device (`who`) and the feature or operation.
HalError to_hal_error(const GError* e, const std::string& who, const char* what, const char* value) {
  const std::string where =
      who + ": " + what + (value ? std::string(" = ") + value : std::string()) + ": " + e->message;
  if (is_gone_error(e))
    return HalError(ErrorCode::DeviceGone, where +
                                               "; the camera stopped answering (unplugged, powered off or its link "
                                               "is down) — check the cable and its power (PoE)");
  if (is_missing_feature_error(e))
    return HalError(ErrorCode::MissingFeature,
                    who + ": GenICam feature '" + what + "' missing (" + e->message +
                        "); check the camera's features (arv-viewer-0.8) against the configuration");
  if (e->domain == ARV_DEVICE_ERROR && e->code == ARV_DEVICE_ERROR_NOT_FOUND)
    return HalError(ErrorCode::DeviceMissing,
                    where +
                        "; check that the camera is powered and cabled, that its IP address is in the NIC's subnet, "
                        "that the firewall lets GigE Vision through (UDP 3956 and the stream port), and the camera id "
                        "(vendor-serial or IP address; arv-viewer-0.8 lists the cameras it finds)");
  if (e->domain == ARV_DEVICE_ERROR &&
      (e->code == ARV_DEVICE_ERROR_NOT_CONTROLLER || e->code == ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED ||
       e->code == ARV_DEVICE_ERROR_PROTOCOL_ERROR_BUSY))
    return HalError(ErrorCode::Io, where +
                                       "; another program controls the camera — close it (arv-viewer, a vendor "
                                       "tool) or wait for its heartbeat to time out");
  return HalError(ErrorCode::Io, where + "; check the value against the camera's range (arv-viewer-0.8)");
}

// A manual setting of the camera (exposure, gain) through Aravis's accessors for it.
struct ManualControl {
  const char* label;         // what the configuration calls it, for errors
  const char* feature;       // GenICam name, for errors
  const char* auto_feature;  // its automatic mode, switched off
  const char* unit;          // appended to values in messages
  const char* purpose;       // why a camera without it is refused
  gboolean (*available)(ArvCamera*, GError**);
  gboolean (*auto_available)(ArvCamera*, GError**);
  void (*set_auto)(ArvCamera*, ArvAuto, GError**);
  void (*bounds)(ArvCamera*, double*, double*, GError**);
  void (*set)(ArvCamera*, double, GError**);
  double (*get)(ArvCamera*, GError**);
};
constexpr ManualControl kExposure{"exposure",
                                  "ExposureTime",
                                  "ExposureAuto",
                                  " us",
                                  "the configured manual exposure cannot be applied",
                                  arv_camera_is_exposure_time_available,
                                  arv_camera_is_exposure_auto_available,
                                  arv_camera_set_exposure_time_auto,
                                  arv_camera_get_exposure_time_bounds,
                                  arv_camera_set_exposure_time,
                                  arv_camera_get_exposure_time};
constexpr ManualControl kGain{"gain",
                              "Gain",
                              "GainAuto",
                              "",
                              "the configured manual gain cannot be applied",
                              arv_camera_is_gain_available,
                              arv_camera_is_gain_auto_available,
                              arv_camera_set_gain_auto,
                              arv_camera_get_gain_bounds,
                              arv_camera_set_gain,
                              arv_camera_get_gain};

}  // namespace

// One open connection to the camera, and the feature accessors every setup step uses (they throw
// HalError naming the device and the feature). The stream is released before the camera: it joins
// its receive thread and frees the buffers it holds; releasing the camera ends its heartbeat thread
// and gives up control (which waits out the GVCP retries when the camera is gone).
struct AravisCamera::Session {
  AravisCamera& owner;
  CameraRef camera;
  StreamRef stream;
  gulong control_lost_handler = 0;

  explicit Session(AravisCamera& o) : owner(o) {}
  ~Session() {
    stream.reset();
    if (camera && control_lost_handler != 0)
      g_signal_handler_disconnect(arv_camera_get_device(camera.get()), control_lost_handler);
    camera.reset();
  }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  void check(ErrorRef& e, const char* what, const char* value = nullptr) const {
    if (e) throw to_hal_error(e.get(), owner.describe(), what, value);
  }
  void write_enum(const char* feature, const char* value) const {
    ErrorRef e;
    arv_camera_set_string(camera.get(), feature, value, e.out());
    check(e, feature, value);
  }
  void write_bool(const char* feature, bool value) const {
    ErrorRef e;
    arv_camera_set_boolean(camera.get(), feature, value ? TRUE : FALSE, e.out());
    check(e, feature, value ? "true" : "false");
  }
  void write_float(const char* feature, double value) const {
    ErrorRef e;
    arv_camera_set_float(camera.get(), feature, value, e.out());
    if (e) check(e, feature, std::to_string(value).c_str());
  }
  std::string read_enum(const char* feature) const {
    ErrorRef e;
    const char* value = arv_camera_get_string(camera.get(), feature, e.out());
    check(e, feature);
    return value ? value : "";
  }
  bool has_feature(const char* feature) const {
    ErrorRef e;
    const bool available = arv_camera_is_feature_available(camera.get(), feature, e.out());
    check(e, feature);
    return available;
  }
  void require_feature(const char* feature, const std::string& purpose) const {
    if (!has_feature(feature))
      throw HalError(ErrorCode::MissingFeature,
                     owner.describe() + ": GenICam feature '" + feature + "' missing: " + purpose);
  }
  std::vector<std::string> enum_entries(const char* feature) const {
    ErrorRef e;
    guint n = 0;
    NameArray names(arv_camera_dup_available_enumerations_as_strings(camera.get(), feature, &n, e.out()));
    check(e, feature);
    std::vector<std::string> out;
    for (guint i = 0; names && i < n; ++i) out.emplace_back(names.get()[i]);
    return out;
  }

  // Sets `control` to `value` (automatic mode off) when one is configured: refused outside the
  // camera's range or on a camera without the feature; returns the value read back (none when
  // not configured).
  std::optional<double> apply_manual(const ManualControl& control, const std::optional<double>& value) const;

  void open();
  void setup_image();
  void setup_controls();
  void setup_strobe();
  void setup_stream();
  bool deliver(ArvBuffer* buffer, Image& out, FrameInfo& info, std::int64_t trigger_ns);
};

AravisCamera::AravisCamera(AravisCameraConfig config) : config_(std::move(config)) {}

AravisCamera::~AravisCamera() {
  deactivate();
  close_session();
  join_releaser();
}

void AravisCamera::join_releaser() noexcept {
  if (releaser_.joinable()) releaser_.join();
}

std::string AravisCamera::describe() const {
  return "Aravis " + config_.camera_id + (model_.empty() ? std::string() : " (" + model_ + ")");
}

// The lifecycle, in one place: which call is allowed in which state, and what to do instead.
void AravisCamera::require_state(Call call) const {
  switch (call) {
    case Call::Configure:
      if (state_ == State::Active)
        throw HalError(ErrorCode::InvalidState, describe() + ": configure() while streaming; deactivate() first");
      return;
    case Call::Activate:
    case Call::SelectLed:
      if (state_ == State::Unconfigured)
        throw HalError(
            ErrorCode::InvalidState,
            describe() + (call == Call::Activate ? ": activate()" : ": select_led()") + " before configure()");
      return;
    case Call::Read:
      if (state_ != State::Active)
        throw HalError(ErrorCode::InvalidState, describe() + ": read() while not streaming; call activate()");
      return;
  }
}

template <typename Op>
void AravisCamera::while_in_use(Op&& op) {
  try {
    op();
  } catch (const HalError& e) {
    if (e.code() == ErrorCode::DeviceGone && session_) mark_gone(e.what());
    throw;
  }
}

void AravisCamera::Session::open() {
  {
    // By id, Aravis opens what its device list holds, else the first answer to a broadcast
    // discovery, which may come back through another NIC than the camera's (then the stream is
    // sent to that NIC's address and never arrives). A fresh device list (about 1 s: it waits
    // for late answers) records each camera with the interface it answered on. An IP address
    // is located by a unicast discovery instead.
    in_addr ip{};
    if (::inet_pton(AF_INET, owner.config_.camera_id.c_str(), &ip) != 1) arv_update_device_list();
    ErrorRef e;
    camera.reset(arv_camera_new(owner.config_.camera_id.c_str(), e.out()));
    if (!camera) {
      check(e, "opening the camera");
      throw HalError(ErrorCode::DeviceMissing, owner.describe() +
                                                   ": no camera with this id answers; check the cable, its "
                                                   "power and the id (arv-viewer-0.8 lists the cameras it finds)");
    }
  }
  // Without the control privilege every write would time out like a vanished camera: say who is at fault.
  if (arv_camera_is_gv_device(camera.get()) &&
      !arv_gv_device_is_controller(ARV_GV_DEVICE(arv_camera_get_device(camera.get()))))
    throw HalError(ErrorCode::Io, owner.describe() +
                                      ": another host or program controls the camera (GigE Vision control "
                                      "privilege); close it (arv-viewer, a vendor tool) or wait for its "
                                      "heartbeat to time out");
  ErrorRef e;
  const char* vendor = arv_camera_get_vendor_name(camera.get(), e.out());
  check(e, "DeviceVendorName");
  const char* model = arv_camera_get_model_name(camera.get(), e.out());
  check(e, "DeviceModelName");
  owner.model_ = std::string(vendor ? vendor : "?") + " " + (model ? model : "?");
  control_lost_handler = g_signal_connect(arv_camera_get_device(camera.get()), "control-lost",
                                          G_CALLBACK(on_control_lost), &owner.control_lost_);
  setup_image();
  setup_controls();
  if (owner.config_.strobe) setup_strobe();
  setup_stream();
}

void AravisCamera::Session::setup_image() {
  const AravisCameraConfig& c = owner.config_;
  if (c.bits_per_pixel != 8 && c.bits_per_pixel != 16)
    throw HalError(ErrorCode::UnsupportedFormat, owner.describe() + ": output depth must be 8 or 16 bit, not " +
                                                     std::to_string(c.bits_per_pixel) + "; check the configuration");
  ArvCamera* cam = camera.get();
  ErrorRef e;
  guint n = 0, n_names = 0;
  ValueArray formats(arv_camera_dup_available_pixel_formats(cam, &n, e.out()));
  check(e, "PixelFormat");
  NameArray names(arv_camera_dup_available_pixel_formats_as_strings(cam, &n_names, e.out()));
  check(e, "PixelFormat");
  bool have_mono8 = false, have_mono16 = false;
  for (guint i = 0; formats && i < n; ++i) {
    const auto f = static_cast<ArvPixelFormat>(formats.get()[i]);
    have_mono8 = have_mono8 || f == ARV_PIXEL_FORMAT_MONO_8;
    have_mono16 = have_mono16 || f == ARV_PIXEL_FORMAT_MONO_16;
  }
  std::vector<std::string> offered;
  for (guint i = 0; names && i < n_names; ++i) offered.emplace_back(names.get()[i]);
  if (!have_mono8 && !have_mono16)
    throw HalError(ErrorCode::UnsupportedFormat, owner.describe() + ": offers neither Mono8 nor Mono16 (offers " +
                                                     join(offered) + "); a colour model needs its mono variant");
  // Prefer the format that already has the wanted depth, as V4L2Camera does; convert_to_grey does the rest.
  const bool use16 = c.bits_per_pixel == 16 ? have_mono16 : !have_mono8;
  owner.source_ = use16 ? SourceFormat::Y16 : SourceFormat::Grey;
  owner.pixel_format_name_ = use16 ? "Mono16" : "Mono8";
  arv_camera_set_pixel_format(cam, use16 ? ARV_PIXEL_FORMAT_MONO_16 : ARV_PIXEL_FORMAT_MONO_8, e.out());
  check(e, "PixelFormat", owner.pixel_format_name_.c_str());

  arv_camera_set_region(cam, 0, 0, c.width, c.height, e.out());
  const bool refused = static_cast<bool>(e);
  if (refused && is_gone_error(e.get())) check(e, "Width/Height");
  e.reset();
  gint x = 0, y = 0, w = 0, h = 0;
  arv_camera_get_region(cam, &x, &y, &w, &h, e.out());
  check(e, "Width/Height");
  if (refused || w != c.width || h != c.height) {
    gint wmin = 0, wmax = 0, hmin = 0, hmax = 0;
    arv_camera_get_width_bounds(cam, &wmin, &wmax, nullptr);
    arv_camera_get_height_bounds(cam, &hmin, &hmax, nullptr);
    throw HalError(ErrorCode::UnsupportedFormat, owner.describe() + ": asked for " + std::to_string(c.width) + "x" +
                                                     std::to_string(c.height) + " " + owner.pixel_format_name_ +
                                                     ", camera gives " + std::to_string(w) + "x" + std::to_string(h) +
                                                     " (width " + std::to_string(wmin) + ".." + std::to_string(wmax) +
                                                     ", height " + std::to_string(hmin) + ".." + std::to_string(hmax) +
                                                     "); check the image size of the camera model against the sensor");
  }
  owner.format_ = ImageFormat{c.width, c.height, c.bits_per_pixel};
}

std::optional<double> AravisCamera::Session::apply_manual(const ManualControl& m,
                                                          const std::optional<double>& value) const {
  if (!value) return std::nullopt;
  ArvCamera* cam = camera.get();
  ErrorRef e;
  if (!m.available(cam, nullptr)) require_feature(m.feature, m.purpose);
  if (m.auto_available(cam, nullptr)) {
    m.set_auto(cam, ARV_AUTO_OFF, e.out());
    check(e, m.auto_feature, "Off");
  }
  double lo = 0, hi = 0;
  m.bounds(cam, &lo, &hi, e.out());
  check(e, m.feature);
  if (*value < lo || *value > hi)
    throw HalError(ErrorCode::Io, owner.describe() + ": " + m.label + " " + std::to_string(*value) + m.unit +
                                      " outside the camera's range " + std::to_string(lo) + ".." + std::to_string(hi) +
                                      m.unit + "; check the configuration");
  m.set(cam, *value, e.out());
  check(e, m.feature, std::to_string(*value).c_str());
  const double applied = m.get(cam, e.out());
  check(e, m.feature);
  return applied;
}

void AravisCamera::Session::setup_controls() {
  const AravisCameraConfig& c = owner.config_;
  ArvCamera* cam = camera.get();
  ErrorRef e;
  arv_camera_set_acquisition_mode(cam, ARV_ACQUISITION_MODE_CONTINUOUS, e.out());
  check(e, "AcquisitionMode", "Continuous");
  // One exposure per TriggerSoftware: the sequencer switches an LED, then asks for its frame.
  const bool software_trigger = arv_camera_is_software_trigger_supported(cam, e.out());
  check(e, "TriggerSoftware");
  if (!software_trigger)
    require_feature("TriggerSoftware",
                    "the camera cannot expose on a software trigger, which the flash sequence needs");
  arv_camera_set_trigger(cam, "Software", e.out());
  check(e, "TriggerMode/TriggerSource", "Software");

  owner.applied_exposure_us_ = apply_manual(kExposure, c.exposure_us);
  owner.applied_gain_ = apply_manual(kGain, c.gain);
}

// The LED driver is fired by the camera: the strobe line carries ExposureActive (or a timer pulse
// started by ExposureStart) while an LED is selected and a dark source otherwise; the select lines
// carry the LED index from three user outputs. The features are checked before anything is
// written, so a camera without digital outputs gets one error naming what it lacks.
void AravisCamera::Session::setup_strobe() {
  const CameraStrobeConfig& s = *owner.config_.strobe;
  const std::string who = owner.describe();
  const std::string purpose =
      "the camera cannot drive the LEDs from its outputs (camera strobe); fire the LEDs over "
      "GPIO instead (lights.type: gpiod) or use a camera with digital outputs";
  for (const char* f : {"LineSelector", "LineMode", "LineSource", "UserOutputSelector", "UserOutputValue"})
    require_feature(f, purpose);

  const std::vector<std::string> lines = enum_entries("LineSelector");
  const std::vector<std::string> used{s.strobe_line, s.select_lines[0], s.select_lines[1], s.select_lines[2]};
  for (std::size_t i = 0; i < used.size(); ++i) {
    if (!contains(lines, used[i]))
      throw HalError(ErrorCode::WrongLine, who + ": line '" + used[i] + "' is not one of the camera's lines (" +
                                               join(lines) +
                                               "); check the strobe and select lines against the camera's I/O manual");
    for (std::size_t j = 0; j < i; ++j)
      if (used[j] == used[i])
        throw HalError(ErrorCode::WrongLine, who + ": line '" + used[i] +
                                                 "' is configured twice; the strobe line and the "
                                                 "three select lines must differ");
  }
  // Every used line becomes an output; an output-only line may refuse the write and must read Output.
  for (const std::string& line : used) {
    write_enum("LineSelector", line.c_str());
    if (read_enum("LineMode") == "Output") continue;
    ErrorRef e;
    arv_camera_set_string(camera.get(), "LineMode", "Output", e.out());
    if (e && is_gone_error(e.get())) check(e, "LineMode", "Output");
    if (e)
      throw HalError(ErrorCode::WrongLine, who + ": line '" + line + "' cannot be switched to an output (" +
                                               e->message + "); wire the LED driver to one of the camera's outputs");
  }

  const std::vector<std::string> outputs = enum_entries("UserOutputSelector");
  write_enum("LineSelector", s.strobe_line.c_str());
  const std::vector<std::string> strobe_sources = enum_entries("LineSource");
  std::string lit;
  if (s.source == StrobeSource::ExposureActive) {
    lit = "ExposureActive";
  } else {
    const std::string timer_purpose =
        "the strobe pulse needs a timer started by ExposureStart; use the exposure_active strobe";
    require_feature("TimerSelector", timer_purpose);
    require_feature("TimerTriggerSource", timer_purpose);
    const std::vector<std::string> timers = enum_entries("TimerSelector");
    if (timers.empty())
      throw HalError(ErrorCode::MissingFeature, who + ": TimerSelector offers no timer; " + timer_purpose);
    write_enum("TimerSelector", timers[0].c_str());
    const std::vector<std::string> triggers = enum_entries("TimerTriggerSource");
    if (!contains(triggers, "ExposureStart"))
      throw HalError(ErrorCode::MissingFeature, who + ": TimerTriggerSource has no 'ExposureStart' (offers " +
                                                    join(triggers) + "); " + timer_purpose);
    write_enum("TimerTriggerSource", "ExposureStart");
    const char* duration = has_feature("TimerDuration") ? "TimerDuration" : "TimerDurationAbs";
    require_feature(duration, "the strobe pulse length (TimerDuration, µs) cannot be set; " + timer_purpose);
    write_float(duration, s.pulse_us);
    for (const char* delay : {"TimerDelay", "TimerDelayAbs"})
      if (has_feature(delay)) {
        write_float(delay, 0.0);
        break;
      }
    lit = timers[0] + "Active";  // SFNC: Timer0 → LineSource Timer0Active
  }
  if (!contains(strobe_sources, lit))
    throw HalError(ErrorCode::MissingFeature, who + ": line '" + s.strobe_line + "' cannot carry " + lit +
                                                  " (LineSource offers " + join(strobe_sources) + ")");
  // Dark: LineSource=Off where the camera has it, else one more user output held low.
  const bool has_off = contains(strobe_sources, "Off");
  const std::size_t needed = has_off ? 3 : 4;
  if (outputs.size() < needed)
    throw HalError(
        ErrorCode::MissingFeature,
        who + ": the camera strobe needs " + std::to_string(needed) + " user outputs (3 LED select lines" +
            (has_off ? std::string() : std::string(" and the strobe's dark state: LineSource has no 'Off'")) +
            "), UserOutputSelector offers " + join(outputs));
  const bool has_inverter = has_feature("LineInverter");
  if (s.strobe_inverted && !has_inverter)
    require_feature("LineInverter", "the strobe line cannot be inverted; wire the LED driver's input active high");
  for (std::size_t k = 0; k < 3; ++k) {
    write_enum("LineSelector", s.select_lines[k].c_str());
    const std::vector<std::string> sources = enum_entries("LineSource");
    if (!contains(sources, outputs[k]))
      throw HalError(ErrorCode::MissingFeature, who + ": line '" + s.select_lines[k] + "' cannot carry " + outputs[k] +
                                                    " (LineSource offers " + join(sources) + ")");
    write_enum("LineSource", outputs[k].c_str());
    if (has_inverter) write_bool("LineInverter", false);
  }
  for (std::size_t k = 0; k < needed; ++k) {  // all low: LED index 0, the dark output dark
    write_enum("UserOutputSelector", outputs[k].c_str());
    write_bool("UserOutputValue", false);
  }
  write_enum("LineSelector", s.strobe_line.c_str());
  if (has_inverter) write_bool("LineInverter", s.strobe_inverted);
  const std::string dark = has_off ? std::string("Off") : outputs[3];
  write_enum("LineSource", dark.c_str());

  for (std::size_t k = 0; k < 3; ++k) owner.select_outputs_[k] = outputs[k];
  owner.strobe_lit_source_ = lit;
  owner.strobe_dark_source_ = dark;
  owner.select_bits_ = {0, 0, 0};
  owner.strobe_lit_ = false;
  owner.selected_led_ = kNoLed;
}

void AravisCamera::Session::setup_stream() {
  const AravisCameraConfig& c = owner.config_;
  ArvCamera* cam = camera.get();
  ErrorRef e;
  if (c.packet_size > 0 && arv_camera_is_gv_device(cam)) {
    arv_camera_gv_set_packet_size(cam, c.packet_size, e.out());
    check(e, "GevSCPSPacketSize", std::to_string(c.packet_size).c_str());
  }
  const guint payload = arv_camera_get_payload(cam, e.out());
  check(e, "PayloadSize");
  const std::size_t image_bytes =
      owner.format_.size_bytes() / owner.format_.bytes_per_pixel() * bytes_per_source_pixel(owner.source_);
  if (payload < image_bytes)
    throw HalError(ErrorCode::UnsupportedFormat, owner.describe() + ": payload of " + std::to_string(payload) +
                                                     " bytes is smaller than the image; check the camera's settings");
  stream.reset(arv_camera_create_stream(cam, nullptr, nullptr, e.out()));
  check(e, "creating the stream");
  if (!stream)
    throw HalError(ErrorCode::Io, owner.describe() +
                                      ": no stream could be opened; check the firewall (GigE Vision "
                                      "stream packets are UDP)");
  // Allocated once; read() pops a filled buffer and pushes the same one back.
  const int count = std::clamp(c.buffer_count, 2, 16);
  for (int i = 0; i < count; ++i) arv_stream_push_buffer(stream.get(), arv_buffer_new_allocate(payload));
}

// Converts one popped buffer into `out` if it holds the negotiated image, and gives the buffer back
// to the stream in every case. Returns false for a buffer to skip: incomplete or not the negotiated
// image (counted as an error buffer), or CLEARED — Aravis's stream thread hands a buffer back
// untouched when a packet cannot start a frame (seen with the simulator under load: frame id 0).
bool AravisCamera::Session::deliver(ArvBuffer* buffer, Image& out, FrameInfo& info, std::int64_t trigger_ns) {
  struct PushBack {
    ArvStream* stream;
    ArvBuffer* buffer;
    ~PushBack() { arv_stream_push_buffer(stream, buffer); }
  } push_back{stream.get(), buffer};

  CameraStats& stats = owner.stats_;
  const ArvBufferStatus status = arv_buffer_get_status(buffer);
  if (status == ARV_BUFFER_STATUS_CLEARED) return false;  // handed back unused: no frame in it
  if (status != ARV_BUFFER_STATUS_SUCCESS) {              // lost packets, size mismatch, aborted
    ++stats.error_buffers;
    return false;
  }
  const ImageFormat& f = owner.format_;
  const std::size_t row_bytes = static_cast<std::size_t>(f.width) * bytes_per_source_pixel(owner.source_);
  std::size_t size = 0;
  const auto* data = static_cast<const std::uint8_t*>(arv_buffer_get_image_data(buffer, &size));
  gint x_padding = 0, y_padding = 0;
  arv_buffer_get_image_padding(buffer, &x_padding, &y_padding);
  const std::size_t stride = row_bytes + static_cast<std::size_t>(std::max(0, x_padding));
  const ArvPixelFormat expected =
      owner.source_ == SourceFormat::Y16 ? ARV_PIXEL_FORMAT_MONO_16 : ARV_PIXEL_FORMAT_MONO_8;
  if (!data || arv_buffer_get_image_width(buffer) != f.width || arv_buffer_get_image_height(buffer) != f.height ||
      arv_buffer_get_image_pixel_format(buffer) != expected ||
      size < stride * static_cast<std::size_t>(f.height - 1) + row_bytes) {
    ++stats.error_buffers;  // not the negotiated image (another program changed the format?)
    return false;
  }
  const std::uint64_t id = arv_buffer_get_frame_id(buffer);
  if (owner.have_frame_id_) stats.dropped_frames += gev_frames_missed_between(owner.last_frame_id_, id);
  owner.last_frame_id_ = id;
  owner.have_frame_id_ = true;
  convert_to_grey(owner.source_, data, stride, out);
  info.timestamp_ns = trigger_ns;
  info.sequence = static_cast<std::uint32_t>(id);
  ++stats.frames;
  return true;
}

void AravisCamera::open_session() {
  control_lost_ = false;
  session_ = std::make_unique<Session>(*this);
  session_->open();
}

void AravisCamera::close_session() noexcept {
  session_.reset();
  acquiring_ = false;
  strobe_lit_ = false;
  select_bits_ = {-1, -1, -1};
}

void AravisCamera::configure() {
  require_state(Call::Configure);
  close_session();
  join_releaser();
  state_ = State::Unconfigured;
  gone_ = restart_ = false;
  silent_triggers_ = 0;
  try {
    open_session();
  } catch (...) {
    close_session();
    throw;
  }
  have_frame_id_ = false;
  state_ = State::Configured;
}

void AravisCamera::start_acquisition() {
  ErrorRef e;
  arv_camera_start_acquisition(session_->camera.get(), e.out());
  session_->check(e, "AcquisitionStart");
  acquiring_ = true;
}

void AravisCamera::stop_acquisition() noexcept {
  if (!session_ || !acquiring_) return;
  acquiring_ = false;
  ErrorRef e;
  arv_camera_stop_acquisition(session_->camera.get(), e.out());
  if (e) syslog(LOG_WARNING, "mfcd hal: %s: AcquisitionStop: %s", describe().c_str(), e->message);
}

void AravisCamera::activate() {
  require_state(Call::Activate);
  if (state_ == State::Active) return;
  if (gone_)
    try_reconnect();  // also starts the acquisition
  else
    while_in_use([&] { start_acquisition(); });
  restart_ = false;
  state_ = State::Active;
}

void AravisCamera::deactivate() {
  if (state_ != State::Active) return;
  stop_acquisition();
  state_ = State::Configured;
}

// Frames that completed before a trigger answer earlier triggers (one whose read() timed out):
// they are never handed out for this one.
void AravisCamera::discard_completed_frames() {
  ArvStream* stream = session_->stream.get();
  while (ArvBuffer* buffer = arv_stream_try_pop_buffer(stream)) {
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    if (status == ARV_BUFFER_STATUS_SUCCESS)
      ++discarded_frames_;
    else if (status != ARV_BUFFER_STATUS_CLEARED)
      ++stats_.error_buffers;
    arv_stream_push_buffer(stream, buffer);
  }
}

// After a frame timeout: AcquisitionStop cancels whatever trigger the camera still holds, so the
// frame of the next trigger is the next frame that arrives.
void AravisCamera::restart_acquisition() {
  stop_acquisition();
  discard_completed_frames();
  start_acquisition();
  restart_ = false;
}

void AravisCamera::mark_gone(const std::string& cause) {
  syslog(LOG_ERR, "mfcd hal: %s", cause.c_str());
  // Released on another thread: tearing down the stream and giving up control each wait out the
  // GVCP retries to the absent camera (about 10 s together with Aravis 0.8's defaults).
  join_releaser();
  releasing_ = true;
  releaser_ = std::thread([this, session = std::move(session_)]() mutable {
    session.reset();
    releasing_ = false;
  });
  close_session();
  if (!gone_) {
    backoff_ = config_.reconnect_backoff_min;
    next_reconnect_ns_ = monotonic_now_ns() + std::chrono::nanoseconds(backoff_).count();
  }
  gone_ = true;
  restart_ = false;
  selected_led_ = kNoLed;
  throw HalError(ErrorCode::DeviceGone, cause + "; reconnecting with backoff");
}

// Reopens the camera no more often than the current backoff, which doubles up to the maximum.
void AravisCamera::try_reconnect() {
  if (releasing_)
    throw HalError(ErrorCode::DeviceGone, describe() +
                                              ": camera gone, still releasing the lost connection (Aravis waits "
                                              "out its GVCP retries); check the cable and its power (PoE)");
  join_releaser();
  const std::int64_t now = monotonic_now_ns();
  if (now < next_reconnect_ns_)
    throw HalError(ErrorCode::DeviceGone, describe() + ": camera gone, next reconnect attempt in " +
                                              std::to_string((next_reconnect_ns_ - now) / 1'000'000) +
                                              " ms; check the cable and its power (PoE)");
  try {
    open_session();
    start_acquisition();
  } catch (const HalError& e) {
    close_session();
    backoff_ = std::min(config_.reconnect_backoff_max, std::max(config_.reconnect_backoff_min, backoff_ * 2));
    next_reconnect_ns_ = monotonic_now_ns() + std::chrono::nanoseconds(backoff_).count();
    throw HalError(ErrorCode::DeviceGone, describe() + ": camera gone, reconnect failed (" + e.what() +
                                              "); retrying in " + std::to_string(backoff_.count()) + " ms");
  }
  gone_ = false;
  restart_ = false;
  have_frame_id_ = false;  // a restarted camera counts its frames from its own start
  backoff_ = std::chrono::milliseconds{0};
  ++stats_.reconnects;
  syslog(LOG_NOTICE, "mfcd hal: %s reconnected", describe().c_str());
}

void AravisCamera::select_led(int led) {
  if (!config_.strobe)
    throw HalError(ErrorCode::InvalidState, describe() + ": select_led() without a camera strobe configuration");
  require_state(Call::SelectLed);
  if (led < kNoLed || led >= kLedCount)
    throw HalError(ErrorCode::InvalidState, describe() + ": LED " + std::to_string(led) + " does not exist (0..7)");
  if (gone_ || !session_) {
    if (led == kNoLed) {  // nothing exposes, so nothing can light
      selected_led_ = kNoLed;
      return;
    }
    throw HalError(ErrorCode::DeviceGone, describe() + ": cannot select LED " + std::to_string(led) +
                                              ": the camera is gone; reconnecting with backoff");
  }
  const CameraStrobeConfig& s = *config_.strobe;
  while_in_use([&] {
    if (led != kNoLed) {
      // The index first, then the strobe: an exposure never flashes a half-switched selection.
      for (std::size_t k = 0; k < 3; ++k) {
        const int bit = (led >> k) & 1;
        if (select_bits_[k] == bit) continue;
        select_bits_[k] = -1;  // unknown until the write succeeded
        session_->write_enum("UserOutputSelector", select_outputs_[k].c_str());
        session_->write_bool("UserOutputValue", bit != 0);
        select_bits_[k] = bit;
      }
      if (!strobe_lit_) {
        session_->write_enum("LineSelector", s.strobe_line.c_str());
        session_->write_enum("LineSource", strobe_lit_source_.c_str());
        strobe_lit_ = true;
      }
    } else if (strobe_lit_) {
      session_->write_enum("LineSelector", s.strobe_line.c_str());
      session_->write_enum("LineSource", strobe_dark_source_.c_str());
      strobe_lit_ = false;
    }
  });
  selected_led_ = led;
}

void AravisCamera::read(Image& out, FrameInfo& info) {
  require_state(Call::Read);
  if (out.format() != format_)
    throw HalError(ErrorCode::InvalidState, describe() + ": read() into an image of the wrong format");
  if (gone_) try_reconnect();
  const auto lost = [&](const char* when) {
    mark_gone(describe() + ": control lost " + when + " (the camera's heartbeat went unanswered)");
  };
  if (control_lost_) lost("before the trigger");
  std::int64_t trigger_ns = 0;
  while_in_use([&] {
    if (restart_) restart_acquisition();
    discard_completed_frames();
    trigger_ns = monotonic_now_ns();  // the exposure cannot start before this
    ErrorRef e;
    arv_camera_software_trigger(session_->camera.get(), e.out());
    session_->check(e, "TriggerSoftware");
  });
  const std::int64_t deadline = trigger_ns + std::chrono::nanoseconds(config_.frame_timeout).count();
  for (;;) {
    const std::int64_t remaining_ns = deadline - monotonic_now_ns();
    if (remaining_ns <= 0) break;
    // Waits in slices of at most 100 ms so that a lost heartbeat ends the wait early.
    const auto wait_us = static_cast<guint64>(std::min<std::int64_t>(remaining_ns / 1000 + 1, 100'000));
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(session_->stream.get(), wait_us);
    if (buffer && session_->deliver(buffer, out, info, trigger_ns)) {
      silent_triggers_ = 0;
      return;
    }
    if (control_lost_) lost("while waiting for a frame");
  }
  ++stats_.timeouts;
  if (++silent_triggers_ >= kSilentTriggersBeforeReopen) {
    silent_triggers_ = 0;
    mark_gone(describe() + ": no frame for " + std::to_string(kSilentTriggersBeforeReopen) +
              " software triggers in a row, across acquisition restarts (the stream is lost); reopening the camera");
  }
  restart_ = true;
  throw HalError(ErrorCode::StreamTimeout,
                 describe() + ": no frame within " + std::to_string(config_.frame_timeout.count()) +
                     " ms of the software trigger (frame timeout); check the network (stream packets dropped by a "
                     "firewall, a packet size above the NIC's MTU), the camera's trigger settings and the cable");
}

}  // namespace mfcd::hal
