#include "mfcd/hal/v4l2_camera.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <syslog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <string>

#include "mfcd/hal/clock.hpp"
#include "mfcd/hal/error.hpp"

namespace mfcd::hal {

namespace {

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do r = ::ioctl(fd, request, arg);
  while (r < 0 && errno == EINTR);
  return r;
}

std::string fourcc_to_string(std::uint32_t fourcc) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>((fourcc >> (8 * i)) & 0xff);
  return s;
}

std::uint32_t fourcc_of(SourceFormat f) {
  switch (f) {
    case SourceFormat::Grey:
      return V4L2_PIX_FMT_GREY;
    case SourceFormat::Y16:
      return V4L2_PIX_FMT_Y16;
    case SourceFormat::Yuyv:
      return V4L2_PIX_FMT_YUYV;
  }
  return 0;
}

std::size_t bytes_per_source_pixel(SourceFormat f) { return f == SourceFormat::Grey ? 1 : 2; }

}  // namespace

V4L2Camera::V4L2Camera(V4L2CameraConfig config) : config_(std::move(config)) {}

V4L2Camera::~V4L2Camera() {
  stream_off();
  close();
}

std::string V4L2Camera::describe() const {
  return "V4L2 " + config_.device + (driver_.empty() ? std::string() : " (" + driver_ + ")");
}

void V4L2Camera::fail(int err, const char* what) {
  const std::string where = describe() + ": " + what + ": " + std::strerror(err);
  if (err == ENODEV || err == ENXIO)
    throw HalError(ErrorCode::DeviceGone,
                   where + "; the device was unplugged or its driver unloaded — check the cable");
  throw HalError(ErrorCode::Io, where + "; check the driver log (dmesg) and v4l2-ctl -d " + config_.device + " --all");
}

void V4L2Camera::open() {
  struct stat st {};
  if (::stat(config_.device.c_str(), &st) != 0)
    throw HalError(ErrorCode::DeviceMissing,
                   "V4L2 " + config_.device + ": no such device node (" + std::strerror(errno) +
                       "); check that the camera is plugged in, its driver is loaded, and the node name "
                       "(v4l2-ctl --list-devices)");
  if (!S_ISCHR(st.st_mode))
    throw HalError(ErrorCode::DeviceMissing, "V4L2 " + config_.device + ": not a character device; check the path");
  fd_.reset(::open(config_.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC));
  if (!fd_) {
    const int err = errno;
    if (err == EACCES)
      throw HalError(ErrorCode::Io, "V4L2 " + config_.device +
                                        ": permission denied; check that the daemon's user is in group 'video'");
    fail(err, "open");
  }
  v4l2_capability cap{};
  if (xioctl(fd_.get(), VIDIOC_QUERYCAP, &cap) < 0) fail(errno, "VIDIOC_QUERYCAP");
  driver_ = reinterpret_cast<const char*>(cap.driver);
  card_ = reinterpret_cast<const char*>(cap.card);
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE) || !(caps & V4L2_CAP_STREAMING))
    throw HalError(ErrorCode::UnsupportedFormat,
                   describe() + ": not a single-planar video capture node with streaming I/O (card \"" + card_ +
                       "\"); check that this is the camera's capture node (v4l2-ctl -d " + config_.device + " -D)");
}

void V4L2Camera::negotiate() {
  if (config_.bits_per_pixel != 8 && config_.bits_per_pixel != 16)
    throw HalError(ErrorCode::UnsupportedFormat, describe() + ": output depth must be 8 or 16 bit, not " +
                                                     std::to_string(config_.bits_per_pixel) +
                                                     "; check the configuration");
  // Prefer a format that already has the wanted depth; YUYV (luma only) is the common fallback.
  const SourceFormat prefer8[] = {SourceFormat::Grey, SourceFormat::Yuyv, SourceFormat::Y16};
  const SourceFormat prefer16[] = {SourceFormat::Y16, SourceFormat::Grey, SourceFormat::Yuyv};
  const SourceFormat* order = config_.bits_per_pixel == 16 ? prefer16 : prefer8;

  std::string offered;
  bool have[3] = {false, false, false};
  for (std::uint32_t i = 0;; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_.get(), VIDIOC_ENUM_FMT, &desc) < 0) break;
    if (!offered.empty()) offered += ' ';
    offered += fourcc_to_string(desc.pixelformat);
    for (int k = 0; k < 3; ++k)
      if (desc.pixelformat == fourcc_of(static_cast<SourceFormat>(k))) have[k] = true;
  }
  int chosen = -1;
  for (int k = 0; k < 3 && chosen < 0; ++k)
    if (have[static_cast<int>(order[k])]) chosen = static_cast<int>(order[k]);
  if (chosen < 0)
    throw HalError(ErrorCode::UnsupportedFormat, describe() + ": offers none of GREY, Y16, YUYV (offers: " + offered +
                                                     "); check the camera's pixel format settings");
  source_ = static_cast<SourceFormat>(chosen);

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<std::uint32_t>(config_.width);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(config_.height);
  fmt.fmt.pix.pixelformat = fourcc_of(source_);
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd_.get(), VIDIOC_S_FMT, &fmt) < 0) {
    if (errno == EBUSY)
      throw HalError(ErrorCode::Io,
                     describe() + ": VIDIOC_S_FMT: device busy; check that no other program is streaming from it");
    fail(errno, "VIDIOC_S_FMT");
  }
  if (fmt.fmt.pix.pixelformat != fourcc_of(source_) || fmt.fmt.pix.width != static_cast<std::uint32_t>(config_.width) ||
      fmt.fmt.pix.height != static_cast<std::uint32_t>(config_.height) ||
      (fmt.fmt.pix.field != V4L2_FIELD_NONE && fmt.fmt.pix.field != V4L2_FIELD_ANY))
    throw HalError(ErrorCode::UnsupportedFormat,
                   describe() + ": asked for " + std::to_string(config_.width) + "x" + std::to_string(config_.height) +
                       " " + fourcc_to_string(fourcc_of(source_)) + " progressive, device offers " +
                       std::to_string(fmt.fmt.pix.width) + "x" + std::to_string(fmt.fmt.pix.height) + " " +
                       fourcc_to_string(fmt.fmt.pix.pixelformat) + "; check the configured size against v4l2-ctl -d " +
                       config_.device + " --list-formats-ext");
  src_stride_ = fmt.fmt.pix.bytesperline ? fmt.fmt.pix.bytesperline
                                         : static_cast<std::size_t>(config_.width) * bytes_per_source_pixel(source_);
  format_ = ImageFormat{config_.width, config_.height, config_.bits_per_pixel};

  // The frame period bounds how long before its timestamp an end-of-frame-stamped frame was exposed.
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (config_.frame_rate > 0) {
    parm.parm.capture.timeperframe = {1, static_cast<std::uint32_t>(config_.frame_rate)};
    if (xioctl(fd_.get(), VIDIOC_S_PARM, &parm) < 0 || parm.parm.capture.timeperframe.numerator == 0 ||
        parm.parm.capture.timeperframe.denominator / parm.parm.capture.timeperframe.numerator !=
            static_cast<std::uint32_t>(config_.frame_rate))
      syslog(LOG_WARNING, "mfcd hal: %s does not run at %d fps at this size; using what it offers", describe().c_str(),
             config_.frame_rate);
    parm = {};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  }
  exposure_lead_ns_ = 0;
  if (xioctl(fd_.get(), VIDIOC_G_PARM, &parm) == 0 && parm.parm.capture.timeperframe.denominator != 0)
    exposure_lead_ns_ = static_cast<std::int64_t>(parm.parm.capture.timeperframe.numerator) * 1'000'000'000 /
                        parm.parm.capture.timeperframe.denominator;
}

void V4L2Camera::apply_controls() {
  auto has = [&](std::uint32_t id, v4l2_queryctrl& q) {
    q = {};
    q.id = id;
    return xioctl(fd_.get(), VIDIOC_QUERYCTRL, &q) == 0 && !(q.flags & V4L2_CTRL_FLAG_DISABLED);
  };
  auto set = [&](std::uint32_t id, std::int32_t value, const char* name) {
    v4l2_control c{id, value};
    if (xioctl(fd_.get(), VIDIOC_S_CTRL, &c) < 0)
      throw HalError(ErrorCode::Io, describe() + ": setting " + name + " to " + std::to_string(value) + ": " +
                                        std::strerror(errno) + "; check the range with v4l2-ctl -d " + config_.device +
                                        " -L");
  };
  v4l2_queryctrl q{};
  exposure_applied_ = gain_applied_ = false;
  if (config_.exposure_us) {
    if (has(V4L2_CID_EXPOSURE_ABSOLUTE, q)) {
      if (has(V4L2_CID_EXPOSURE_AUTO, q)) set(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "exposure mode");
      set(V4L2_CID_EXPOSURE_ABSOLUTE, std::max(1, *config_.exposure_us / 100), "exposure (100 us units)");
      exposure_applied_ = true;
    } else {
      syslog(LOG_WARNING, "mfcd hal: %s has no exposure control; the configured %d us is not applied",
             describe().c_str(), *config_.exposure_us);
    }
  }
  if (config_.gain) {
    if (has(V4L2_CID_GAIN, q)) {
      if (*config_.gain < q.minimum || *config_.gain > q.maximum)
        throw HalError(ErrorCode::Io, describe() + ": gain " + std::to_string(*config_.gain) +
                                          " outside the device's range " + std::to_string(q.minimum) + ".." +
                                          std::to_string(q.maximum) + "; check the configuration");
      if (has(V4L2_CID_AUTOGAIN, q)) set(V4L2_CID_AUTOGAIN, 0, "automatic gain");
      set(V4L2_CID_GAIN, *config_.gain, "gain");
      gain_applied_ = true;
    } else {
      syslog(LOG_WARNING, "mfcd hal: %s has no gain control; the configured gain is not applied", describe().c_str());
    }
  }
}

void V4L2Camera::allocate_buffers() {
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(std::clamp(config_.buffer_count, 2, kMaxBuffers));
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_.get(), VIDIOC_REQBUFS, &req) < 0) fail(errno, "VIDIOC_REQBUFS (mmap streaming)");
  if (req.count < 2)
    throw HalError(ErrorCode::Io, describe() + ": driver granted only " + std::to_string(req.count) +
                                      " buffer(s); check available memory (CMA) for the camera");
  buffer_count_ = static_cast<int>(std::min<std::uint32_t>(req.count, kMaxBuffers));
  for (int i = 0; i < buffer_count_; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = static_cast<std::uint32_t>(i);
    if (xioctl(fd_.get(), VIDIOC_QUERYBUF, &b) < 0) fail(errno, "VIDIOC_QUERYBUF");
    if (i == 0 && (b.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_SOE)
      exposure_lead_ns_ = 0;  // stamped at start of exposure: no lead
    if ((b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC)
      syslog(LOG_WARNING, "mfcd hal: %s does not stamp buffers with CLOCK_MONOTONIC; LED windows cannot be verified",
             describe().c_str());
    void* p = ::mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_.get(), b.m.offset);
    if (p == MAP_FAILED) fail(errno, "mmap of a capture buffer");
    buffers_[static_cast<std::size_t>(i)] = {p, b.length};
  }
  if (src_stride_ * static_cast<std::size_t>(format_.height) > buffers_[0].length)
    throw HalError(ErrorCode::UnsupportedFormat,
                   describe() + ": capture buffers smaller than the negotiated image; check the driver");
}

void V4L2Camera::release_buffers() {
  for (int i = 0; i < buffer_count_; ++i) {
    Mapping& m = buffers_[static_cast<std::size_t>(i)];
    if (m.data) ::munmap(m.data, m.length);
    m = {};
  }
  if (buffer_count_ > 0 && fd_) {
    v4l2_requestbuffers req{};
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    xioctl(fd_.get(), VIDIOC_REQBUFS, &req);  // count 0 frees the driver's buffers; failure is harmless here
  }
  buffer_count_ = 0;
}

void V4L2Camera::close() noexcept {
  release_buffers();
  fd_.reset();
  streaming_ = false;
}

void V4L2Camera::configure() {
  if (active_)
    throw HalError(ErrorCode::InvalidState, describe() + ": configure() while streaming; deactivate() first");
  close();
  try {
    open();
    negotiate();
    apply_controls();
    allocate_buffers();
  } catch (...) {
    close();
    throw;
  }
  gone_ = false;
  configured_ = true;
}

void V4L2Camera::stream_on() {
  for (int i = 0; i < buffer_count_; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = static_cast<std::uint32_t>(i);
    if (xioctl(fd_.get(), VIDIOC_QBUF, &b) < 0) fail(errno, "VIDIOC_QBUF");
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_.get(), VIDIOC_STREAMON, &type) < 0) {
    const int err = errno;
    xioctl(fd_.get(), VIDIOC_STREAMOFF, &type);  // hand the queued buffers back
    fail(err, "VIDIOC_STREAMON");
  }
  streaming_ = true;
  have_sequence_ = false;
}

void V4L2Camera::stream_off() noexcept {
  if (!streaming_ || !fd_) return;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  xioctl(fd_.get(), VIDIOC_STREAMOFF, &type);  // also dequeues every buffer
  streaming_ = false;
}

void V4L2Camera::activate() {
  if (!configured_) throw HalError(ErrorCode::InvalidState, describe() + ": activate() before configure()");
  if (gone_) try_reconnect();
  if (!streaming_) stream_on();
  restart_stream_ = false;
  active_ = true;
}

void V4L2Camera::deactivate() {
  stream_off();
  active_ = false;
}

// After ENODEV every fd is closed (drivers only come back once all handles are gone); reopening is
// attempted from read() no more often than the current backoff, which doubles up to the maximum.
void V4L2Camera::try_reconnect() {
  const std::int64_t now = monotonic_now_ns();
  if (now < next_reconnect_ns_)
    throw HalError(ErrorCode::DeviceGone, describe() + ": device gone, next reconnect attempt in " +
                                              std::to_string((next_reconnect_ns_ - now) / 1'000'000) +
                                              " ms; check the cable");
  try {
    open();
    negotiate();
    apply_controls();
    allocate_buffers();
    stream_on();
  } catch (const HalError& e) {
    close();
    backoff_ = std::min(config_.reconnect_backoff_max, std::max(config_.reconnect_backoff_min, backoff_ * 2));
    next_reconnect_ns_ = monotonic_now_ns() + std::chrono::nanoseconds(backoff_).count();
    throw HalError(ErrorCode::DeviceGone, describe() + ": device gone, reconnect failed (" + e.what() +
                                              "); retrying in " + std::to_string(backoff_.count()) + " ms");
  }
  gone_ = false;
  backoff_ = std::chrono::milliseconds{0};
  ++stats_.reconnects;
  syslog(LOG_NOTICE, "mfcd hal: %s reconnected", describe().c_str());
}

void V4L2Camera::read(Image& out, FrameInfo& info) {
  if (!active_) throw HalError(ErrorCode::InvalidState, describe() + ": read() while not streaming; call activate()");
  if (out.format() != format_)
    throw HalError(ErrorCode::InvalidState, describe() + ": read() into an image of the wrong format");
  if (gone_) try_reconnect();
  if (restart_stream_) {  // after a watchdog expiry or a fatal queue error: restart the stream
    stream_off();
    stream_on();
    restart_stream_ = false;
  }
  auto mark_gone = [&](const char* what) {
    const int err = errno;
    close();
    gone_ = true;
    backoff_ = config_.reconnect_backoff_min;
    next_reconnect_ns_ = monotonic_now_ns() + std::chrono::nanoseconds(backoff_).count();
    syslog(LOG_ERR, "mfcd hal: %s: %s: %s", describe().c_str(), what, std::strerror(err));
    throw HalError(ErrorCode::DeviceGone, describe() + ": " + what + ": " + std::strerror(err) +
                                              "; the camera was unplugged or its driver reset — check the cable; "
                                              "reconnecting with backoff");
  };

  const std::int64_t deadline = monotonic_now_ns() + std::chrono::nanoseconds(config_.dequeue_timeout).count();
  for (;;) {
    const std::int64_t remaining = deadline - monotonic_now_ns();
    pollfd p{fd_.get(), POLLIN, 0};
    const int r = remaining > 0 ? ::poll(&p, 1, static_cast<int>((remaining + 999'999) / 1'000'000)) : 0;
    if (r < 0) {
      if (errno == EINTR) continue;
      fail(errno, "poll");
    }
    if (r == 0) {
      ++stats_.timeouts;
      restart_stream_ = true;
      throw HalError(ErrorCode::StreamTimeout,
                     describe() + ": no frame within " + std::to_string(config_.dequeue_timeout.count()) +
                         " ms (dequeue watchdog); check the frame rate, the trigger wiring and the cable");
    }
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_.get(), VIDIOC_DQBUF, &b) < 0) {
      if (errno == EAGAIN) continue;
      if (errno == ENODEV || errno == ENXIO) mark_gone("VIDIOC_DQBUF");
      if (errno == EIO || errno == EPIPE) {  // queue in error state: the stream must be restarted
        restart_stream_ = true;
        fail(errno, "VIDIOC_DQBUF (streaming error, restarting the stream)");
      }
      fail(errno, "VIDIOC_DQBUF");
    }
    const auto requeue = [&] {
      if (xioctl(fd_.get(), VIDIOC_QBUF, &b) < 0) {
        if (errno == ENODEV || errno == ENXIO) mark_gone("VIDIOC_QBUF");
        fail(errno, "VIDIOC_QBUF");
      }
    };
    if (b.flags & V4L2_BUF_FLAG_ERROR) {  // corrupt frame: give the buffer back and wait for the next
      ++stats_.error_buffers;
      last_sequence_ = b.sequence;
      have_sequence_ = true;
      requeue();
      continue;
    }
    if (have_sequence_) stats_.dropped_frames += frames_missed_between(last_sequence_, b.sequence);
    last_sequence_ = b.sequence;
    have_sequence_ = true;
    if (b.index >= static_cast<std::uint32_t>(buffer_count_) ||
        b.bytesused < src_stride_ * static_cast<std::size_t>(format_.height)) {
      ++stats_.error_buffers;  // short frame: treat like an error buffer
      requeue();
      continue;
    }
    convert_to_grey(source_, static_cast<const std::uint8_t*>(buffers_[b.index].data), src_stride_, out);
    info.timestamp_ns = static_cast<std::int64_t>(b.timestamp.tv_sec) * 1'000'000'000 +
                        static_cast<std::int64_t>(b.timestamp.tv_usec) * 1000;
    info.sequence = b.sequence;
    ++stats_.frames;
    requeue();
    return;
  }
}

}  // namespace mfcd::hal
