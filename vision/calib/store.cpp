#include "vision/calib/store.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "base/unique_fd.hpp"

namespace mfcd::vision::calib {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void sys_fail(const fs::path& p, const std::string& what) {
  throw std::runtime_error(p.string() + ": " + what + ": " + std::strerror(errno));
}

void fsync_path(const fs::path& p, bool directory) {
  const UniqueFd fd(::open(p.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC));
  if (!fd) sys_fail(p, "cannot open to fsync");
  if (::fsync(fd.get()) != 0) sys_fail(p, "fsync failed");  // errno is read before fd closes
}

fs::path directory_of(const fs::path& file) {
  const fs::path d = file.parent_path();
  return d.empty() ? fs::path(".") : d;
}

// A unique temporary name beside `file`, ending in .yaml so FileStorage writes YAML.
fs::path temp_beside(const fs::path& file) {
  static std::atomic<unsigned> counter{0};
  // Built with append: GCC 12 warns falsely (-Wrestrict) on a chain of operator+.
  std::string name(".");
  name.append(file.filename().string()).append(".tmp-").append(std::to_string(::getpid()));
  name.append("-").append(std::to_string(counter++)).append(".yaml");
  return directory_of(file) / name;
}

bool same_config(const CameraConfig& a, const CameraConfig& b) {
  if (a.camera.image_size != b.camera.image_size || a.camera.K != b.camera.K ||
      a.camera.distortion != b.camera.distortion || a.working_distance_mm != b.working_distance_mm ||
      a.flashes.positions_mm != b.flashes.positions_mm || a.hand_eye.has_value() != b.hand_eye.has_value())
    return false;
  if (a.hand_eye)
    return a.hand_eye->mode == b.hand_eye->mode && a.hand_eye->camera_pose == b.hand_eye->camera_pose &&
           a.hand_eye->views == b.hand_eye->views;
  return true;
}

// Writes and syncs a temporary copy of `config`; returns its path. The caller renames it.
fs::path write_temp(const CameraConfig& config, const fs::path& file, const CalibrationStore::FaultHook& hook) {
  const fs::path tmp = temp_beside(file);
  try {
    save_camera_config(config, tmp);
    if (!fs::exists(tmp)) throw std::runtime_error(tmp.string() + ": not written");
    if (hook) hook("temp-written");
    fsync_path(tmp, false);
    if (hook) hook("temp-synced");
    // Read back: what lands on disk must load to the same configuration.
    if (!same_config(load_camera_config(tmp), config))
      throw std::runtime_error(tmp.string() + ": read back differs from what was written");
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw std::runtime_error(file.string() + ": calibration not written (nothing changed): " + e.what());
  }
  return tmp;
}

void rename_over(const fs::path& tmp, const fs::path& file) {
  if (::rename(tmp.c_str(), file.c_str()) != 0) {
    const int e = errno;
    std::error_code ec;
    fs::remove(tmp, ec);
    errno = e;
    sys_fail(file, "rename of the new calibration failed (nothing changed)");
  }
  fsync_path(directory_of(file), true);
}

}  // namespace

void write_camera_config_atomically(const CameraConfig& config, const fs::path& file) {
  rename_over(write_temp(config, file, {}), file);
}

CalibrationStore::CalibrationStore(fs::path camera_file, FaultHook hook)
    : file_(std::move(camera_file)), hook_(std::move(hook)) {}

fs::path CalibrationStore::previous_file() const { return fs::path(file_.string() + ".previous"); }

std::optional<CameraConfig> CalibrationStore::current() const {
  if (!fs::exists(file_)) return std::nullopt;
  return load_camera_config(file_);
}

std::optional<CameraConfig> CalibrationStore::previous() const {
  if (!fs::exists(previous_file())) return std::nullopt;
  return load_camera_config(previous_file());
}

void CalibrationStore::write_atomically(const CameraConfig& config) { install(write_temp(config, file_, hook_)); }

void CalibrationStore::install(const fs::path& tmp) {
  try {
    if (fs::exists(file_)) {
      // Keep the file being replaced: a hard link to its inode (the rename below only
      // moves the name), renamed into place so .previous is never half-written.
      const fs::path keep = temp_beside(previous_file());
      if (::link(file_.c_str(), keep.c_str()) != 0) {
        std::error_code ec;
        fs::copy_file(file_, keep, ec);
        if (ec) sys_fail(keep, "cannot keep the previous calibration");
        fsync_path(keep, false);
      }
      if (::rename(keep.c_str(), previous_file().c_str()) != 0) {
        const int e = errno;
        std::error_code ec;
        fs::remove(keep, ec);
        errno = e;
        sys_fail(previous_file(), "cannot keep the previous calibration");
      }
      if (hook_) hook_("previous-kept");
    }
    if (hook_) hook_("before-rename");
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  rename_over(tmp, file_);
  if (hook_) hook_("renamed");
}

void CalibrationStore::apply(const CameraConfig& config) { write_atomically(config); }

void CalibrationStore::rollback() {
  if (!fs::exists(previous_file()))
    throw std::runtime_error(file_.string() + ": no previous calibration to roll back to (" + previous_file().string() +
                             " missing)");
  // Restored byte for byte (the operator's comments and number formatting included), after
  // checking that it still loads.
  load_camera_config(previous_file());
  const fs::path tmp = temp_beside(file_);
  try {
    fs::copy_file(previous_file(), tmp);
    if (hook_) hook_("temp-written");
    fsync_path(tmp, false);
    if (hook_) hook_("temp-synced");
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw std::runtime_error(file_.string() + ": rollback not done (nothing changed): " + e.what());
  }
  install(tmp);
}

}  // namespace mfcd::vision::calib
