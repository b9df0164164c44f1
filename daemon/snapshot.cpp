#include "daemon/snapshot.hpp"

#include <algorithm>
#include <ctime>
#include <fstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "daemon/report.hpp"
#include "daemon/retained_job.hpp"
#include "daemon/vision_stage.hpp"
#include "tools/common/build_version.hpp"
#include "vision/dataset/bop_dataset.hpp"

namespace mfcd::daemon {

namespace {

std::uintmax_t directory_size(const fs::path& dir) {
  std::uintmax_t total = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec))
    if (it->is_regular_file(ec)) total += it->file_size(ec);
  return total;
}

// ": no space left (N kB free)" when the file system of `dir` is full, the usual reason a write
// fails; else nothing.
std::string space_note(const fs::path& dir) {
  std::error_code ec;
  const fs::space_info space = fs::space(dir, ec);
  if (!ec && space.available < (1u << 20))
    return ": no space left (" + std::to_string(space.available / 1024) + " kB free)";
  return "";
}

std::string write_failure(const fs::path& file) {
  return "cannot write " + file.string() + space_note(file.parent_path());
}

void write_png(const fs::path& file, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(file.string(), image);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error("snapshot: " + write_failure(file));
}

void copy_or_throw(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
  if (ec)
    throw std::runtime_error("snapshot: cannot copy " + from.string() + " to " + to.string() + ": " + ec.message());
}

// A new directory for cycle `cycle` saved now: <UTC time>-cycle<N>, with -2, -3, ... when the
// cycle was saved before within the same second (a failed cycle, then its failed pick).
fs::path new_snapshot_dir(const fs::path& root, std::uint64_t cycle) {
  char stamp[32];
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
  const std::string base = std::string(stamp) + "-cycle" + std::to_string(cycle);
  fs::path dir = root / base;
  for (int k = 2; fs::exists(dir); ++k) dir = root / (base + "-" + std::to_string(k));
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("snapshot: cannot create " + dir.string() + ": " + ec.message());
  return dir;
}

}  // namespace

SnapshotWriter::SnapshotWriter(const DaemonConfig& config) : config_(config) {
  try {
    camera_ = vision::load_camera_config(config.camera.model);
  } catch (const std::exception& e) {
    replay_error_ = std::string("the camera file cannot be read: ") + e.what();
    return;
  }
  try {
    vision::ReplayManifest m = vision::make_replay_manifest(pipeline_config(config));
    m.version = version();
    m.commit = git_commit();
    replay_ = std::move(m);
  } catch (const std::exception& e) {
    replay_error_ = e.what();
  }
}

std::string SnapshotWriter::save(const RetainedJob& job, const VisionStage* stage, const char* reason) const {
  const fs::path root = config_.snapshots.directory;
  std::error_code ec;
  fs::create_directories(root, ec);
  if (ec) throw std::runtime_error("snapshot: cannot create " + root.string() + ": " + ec.message());

  // Quota: a snapshot is about 9 images + 3 (the gray/ copy, edges, overlay); keep the total
  // under the quota by deleting the oldest snapshot directories (names sort by time).
  const std::uintmax_t estimate = 12 * job.slot().frames.frames[0].image.size_bytes();
  std::vector<fs::path> existing;
  for (const auto& e : fs::directory_iterator(root, ec))
    if (e.is_directory()) existing.push_back(e.path());
  std::sort(existing.begin(), existing.end());
  std::uintmax_t used = directory_size(root);
  for (const auto& old : existing) {
    if (used + estimate <= config_.snapshots.quota_bytes) break;
    const std::uintmax_t size = directory_size(old);
    fs::remove_all(old, ec);
    used = used > size ? used - size : 0;
  }
  if (used + estimate > config_.snapshots.quota_bytes)
    throw std::runtime_error("snapshot: quota of " + std::to_string(config_.snapshots.quota_bytes >> 20) + " MB in " +
                             root.string() + " is too small for one snapshot");

  const fs::path dir = new_snapshot_dir(root, job.result().request.cycle_id);
  try {
    write_files(dir, job, stage, reason);
  } catch (...) {
    fs::remove_all(dir, ec);  // no half snapshot is left to be taken for a whole one
    throw;
  }
  return dir.string();
}

void SnapshotWriter::write_files(const fs::path& dir, const RetainedJob& job, const VisionStage* stage,
                                 const char* reason) const {
  const FrameSlot& slot = job.slot();
  const CycleResult& result = job.result();
  std::string replayable = replay_error_;
  if (slot.ok) {
    if (camera_) {
      write_scene(dir, job);
    }
    if (result.error == CycleError::None && stage) {
      if (const cv::Mat1b* edges = job.edges()) write_png(dir / "edges.png", *edges);
      // Overlay on the brightest-flash composite, where every outline is lit.
      cv::Mat composite = slot.mfc.flash[0].clone();
      for (int k = 1; k < hal::kLedCount; ++k)
        cv::max(composite, cv::Mat(slot.mfc.flash[static_cast<std::size_t>(k)]), composite);
      write_png(dir / "overlay.png", stage->overlay(cv::Mat1b(composite), overlay_candidates(result, stage->parts())));
    }
  } else {
    replayable = "the capture failed: no images";
  }
  CycleResult with_dir = result;
  copy_message(with_dir.snapshot_dir, sizeof with_dir.snapshot_dir, dir.c_str());
  nlohmann::json j = result_json(with_dir, config_);
  j["snapshot_reason"] = reason;
  j["replayable"] = replayable.empty() ? nlohmann::json(true) : nlohmann::json(replayable);
  std::ofstream out(dir / "result.json");
  out << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  // close() flushes: a full disk shows here, not in the << above.
  out.close();
  if (out.fail()) throw std::runtime_error("snapshot: " + write_failure(dir / "result.json"));
}

// The one-image BOP scene (the frames as the pipeline saw them: undistorted, so the camera's K
// without distortion describes them), the replay manifest and the copied files.
void SnapshotWriter::write_scene(const fs::path& dir, const RetainedJob& job) const {
  const FrameSlot& slot = job.slot();
  std::vector<vision::BopGtPose> truth;
  for (int i = 0; i < slot.truth.count; ++i) {
    const SimTruth::Part& p = slot.truth.parts[static_cast<std::size_t>(i)];
    truth.push_back({p.obj_id, p.R, p.t_mm});
  }
  try {
    vision::BopWriter bop(dir, "test");
    bop.write_models({});  // the parts are in the template files the manifest names
    bop.write_camera(*camera_);
    bop.write_capture(1, *camera_, slot.mfc, truth);
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("snapshot: ") + e.what() + space_note(dir));
  }
  copy_or_throw(config_.camera.model, dir / "camera.yaml");
  std::error_code ec;
  if (fs::is_regular_file(config_.source, ec)) copy_or_throw(config_.source, dir / "mfcd.yaml");
  if (replay_) {
    vision::ReplayManifest m = *replay_;
    m.cycle = job.result().request.cycle_id;
    m.obj_id = slot.request.obj_id;
    vision::write_replay_manifest(m, dir / vision::kReplayManifestName);
  }
}

}  // namespace mfcd::daemon
