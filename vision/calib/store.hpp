#pragma once
// Applies a calibration to the camera YAML the rest of the project reads, atomically, and
// keeps the file it replaces for rollback.
//
// apply(): the new config is validated and written to a temporary file in the same
// directory, fsync'ed, read back and compared, then the current file is kept as
// "<file>.previous" (hard link, else copy) and the temporary renamed over the file; the
// directory is fsync'ed last. On any error the temporary is removed and the camera file is
// untouched. rollback() does the same with a byte-for-byte copy of the previous file, so a
// second rollback undoes the first.

#include "vision/camera/camera.hpp"

#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace mfcd::vision::calib {

class CalibrationStore {
 public:
  // Called at each step ("temp-written", "temp-synced", "previous-kept", "renamed"); the
  // tests throw from it to check that a failure at any step leaves the old file.
  using FaultHook = std::function<void(const std::string& step)>;

  explicit CalibrationStore(std::filesystem::path camera_file, FaultHook hook = {});

  const std::filesystem::path& file() const { return file_; }
  std::filesystem::path previous_file() const;

  std::optional<CameraConfig> current() const;   // nullopt when the file does not exist
  std::optional<CameraConfig> previous() const;  // nullopt when there is nothing to roll back to

  // Throws std::runtime_error naming the file and the failed step.
  void apply(const CameraConfig& config);
  // Restores the previous file; throws when there is none.
  void rollback();

 private:
  void write_atomically(const CameraConfig& config);
  // Keeps the current file as .previous and renames the (synced) temporary `tmp` over it.
  void install(const std::filesystem::path& tmp);
  std::filesystem::path file_;
  FaultHook hook_;
};

// Writes `config` to `file` atomically (temporary + fsync + rename + directory fsync)
// without keeping a previous copy.
void write_camera_config_atomically(const CameraConfig& config, const std::filesystem::path& file);

}  // namespace mfcd::vision::calib
