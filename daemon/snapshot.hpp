#pragma once
// Snapshots: a kept cycle (RetainedJob) saved as a directory an operator can look at and that
// mfc-detect runs again as the cycle ran it (docs/operations.md "Snapshots"):
//   result.json, overlay.png, edges.png   what the cycle found, and why it was saved
//   camera.json, models/, test/000001/    a one-image BOP scene with the flash images (docs/datasets.md)
//   mfcd_replay.json                      template files (path, size, CRC-32), pipeline settings, part type
//   camera.yaml, mfcd.yaml                copies of the camera file and of the configuration file
// Written by the vision worker after the cycle's result has been handed over; off the frame path.
#include <optional>
#include <string>

#include "daemon/config.hpp"
#include "vision/camera/camera.hpp"
#include "vision/pipeline/replay_manifest.hpp"

namespace mfcd::daemon {

class RetainedJob;
class VisionStage;

class SnapshotWriter {
 public:
  // Reads what every snapshot of this configuration shares: the camera file and, when every
  // recipe names a template file, the replay manifest (the files' CRCs: read once, here). Never
  // throws: what cannot be had is recorded, and the snapshots say they are not replayable and why.
  explicit SnapshotWriter(const DaemonConfig& config);

  // Saves `job` into a new directory under snapshots.directory, first deleting the oldest
  // snapshots while the directory's size would exceed the quota. Returns the new directory.
  // Throws std::runtime_error naming the path on failure; no half-written snapshot is left.
  std::string save(const RetainedJob& job, const VisionStage* stage, const char* reason) const;

  // Empty when snapshots are replayable; else why not.
  const std::string& not_replayable() const { return replay_error_; }

 private:
  void write_files(const std::filesystem::path& dir, const RetainedJob& job, const VisionStage* stage,
                   const char* reason) const;
  void write_scene(const std::filesystem::path& dir, const RetainedJob& job) const;

  DaemonConfig config_;
  std::optional<vision::CameraConfig> camera_;
  std::optional<vision::ReplayManifest> replay_;
  std::string replay_error_;
};

}  // namespace mfcd::daemon
