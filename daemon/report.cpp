#include "daemon/report.hpp"

#include <algorithm>
#include <ctime>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "daemon/retained_job.hpp"
#include "daemon/vision_stage.hpp"
#include "tools/common/build_version.hpp"
#include "motion/pick_transform.hpp"

namespace mfcd::daemon {

using nlohmann::json;

std::optional<motion::PickPose> basePose(const DaemonConfig& config, const cv::Matx33d& R, const cv::Vec3d& t) {
  Eigen::Isometry3d cam_T_part = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) cam_T_part.linear()(r, k) = R(r, k);
    cam_T_part.translation()(r) = t[r];
  }
  return motion::PickTransform(config.hand_eye).pick_pose(cam_T_part);
}

json poseJson(const motion::PickPose& p) {
  return {{"x", p.x_mm}, {"y", p.y_mm}, {"z", p.z_mm}, {"rx", p.rx_deg}, {"ry", p.ry_deg}, {"rz", p.rz_deg}};
}

namespace {
json matJson(const cv::Matx33d& R) {
  json a = json::array();
  for (int i = 0; i < 9; ++i) a.push_back(R.val[i]);
  return a;
}
const char* errorName(CycleError e) {
  switch (e) {
    case CycleError::None: return "none";
    case CycleError::UnknownRecipe: return "unknown recipe";
    case CycleError::Capture: return "capture failed";
    case CycleError::Vision: return "vision failed";
    case CycleError::Transform: return "pick transform failed";
    case CycleError::Abandoned: return "abandoned";
    case CycleError::Calibrating: return "calibrating";
    case CycleError::Unavailable: return "cell unavailable";
  }
  return "?";
}
}  // namespace

json resultJson(const CycleResult& r, const DaemonConfig& config) {
  json j;
  j["version"] = version();  // which mfcd made the result (result.json outlives the daemon)
  j["commit"] = git_commit();
  j["cycle"] = r.request.cycle_id;
  j["origin"] = toString(r.request.origin);
  j["job_id"] = r.request.job_id;
  j["recipe"] = r.request.recipe_id;
  if (const RecipeConfig* rc = config.recipe(r.request.recipe_id)) j["part"] = rc->part;
  j["mode"] = r.request.mode == 0 ? "pick" : "count";
  j["error_code"] = static_cast<int>(r.error);
  j["error"] = errorName(r.error);
  if (r.message[0]) j["message"] = r.message;
  j["degraded"] = r.degraded;
  j["overrun"] = r.total_ms > config.cycle_budget_ms;
  j["leds_off_after_capture"] = r.leds_off;
  j["times_ms"] = {{"capture", r.capture_ms}, {"queue", r.queue_ms}, {"vision", r.vision_ms},
                   {"choice", r.choice_ms},   {"total", r.total_ms},   {"edges", r.edges_ms},
                   {"lines", r.lines_ms},     {"distance", r.distance_ms}, {"search", r.search_ms},
                   {"pose", r.pose_ms},       {"refine", r.refine_ms}};
  j["budget_ms"] = config.cycle_budget_ms;
  j["edge_pixels"] = r.edge_pixels;
  j["search_rounds"] = r.search_rounds;
  j["escalated"] = r.escalated;
  json cands = json::array();
  for (int i = 0; i < r.candidate_count; ++i) {
    const CandidateOut& c = r.candidates[static_cast<std::size_t>(i)];
    json cj = {{"obj_id", c.obj_id}, {"score", c.score}, {"cost_px", c.cost_px}, {"refined", c.refined},
               {"utility", c.utility}, {"grasp_visibility", c.grasp_visibility}, {"ambiguous", c.ambiguous},
               {"R_cam", matJson(c.R_cam)},
               {"t_cam_mm", {c.t_cam_mm[0], c.t_cam_mm[1], c.t_cam_mm[2]}}};
    if (c.base_valid) cj["base"] = poseJson(c.base);
    cands.push_back(std::move(cj));
  }
  j["candidates"] = std::move(cands);
  j["chosen"] = r.chosen;
  // The pick order (candidate indices, best first) the robot link's NEXT walks.
  j["ranked"] = std::vector<int>(r.ranked.begin(), r.ranked.begin() + std::max(0, r.ranked_count));
  if (r.chosen >= 0) {
    const CandidateOut& c = r.candidates[static_cast<std::size_t>(r.chosen)];
    j["pick"] = poseJson(c.base);
    j["pick"]["score"] = c.score;
    j["pick"]["obj_id"] = c.obj_id;
  }
  if (r.truth.count > 0) {
    json truth = json::array();
    for (int i = 0; i < r.truth.count; ++i) {
      const SimTruth::Part& p = r.truth.parts[static_cast<std::size_t>(i)];
      json tj = {{"obj_id", p.obj_id}, {"R_cam", matJson(p.R)}, {"t_cam_mm", {p.t_mm[0], p.t_mm[1], p.t_mm[2]}}};
      if (const auto b = basePose(config, p.R, p.t_mm)) tj["base"] = poseJson(*b);
      truth.push_back(std::move(tj));
    }
    j["sim_truth"] = std::move(truth);
  }
  if (r.snapshot_dir[0]) j["snapshot"] = r.snapshot_dir;
  return j;
}

namespace {

std::uintmax_t directorySize(const fs::path& dir) {
  std::uintmax_t total = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
    if (it->is_regular_file(ec)) total += it->file_size(ec);
  return total;
}

// Why a write into `dir` failed, as far as the file system tells: a full disk is the usual cause.
std::string writeFailure(const fs::path& file) {
  std::error_code ec;
  const fs::space_info space = fs::space(file.parent_path(), ec);
  if (!ec && space.available < (1u << 20))
    return "cannot write " + file.string() + ": no space left (" + std::to_string(space.available / 1024) + " kB free)";
  return "cannot write " + file.string();
}

void writePng(const fs::path& file, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(file.string(), image);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error("snapshot: " + writeFailure(file));
}

void writeSnapshotFiles(const fs::path& dir, const DaemonConfig& config, const RetainedJob& job, const VisionStage* stage,
                        const char* reason);

}  // namespace

std::string saveSnapshot(const DaemonConfig& config, const RetainedJob& job, const VisionStage* stage, const char* reason) {
  const FrameSlot& slot = job.slot();
  const CycleResult& result = job.result();
  const fs::path root = config.snapshots.directory;
  std::error_code ec;
  fs::create_directories(root, ec);
  if (ec) throw std::runtime_error("snapshot: cannot create " + root.string() + ": " + ec.message());

  // Quota: a snapshot is about 9 images + 2; keep the total under the quota by deleting the oldest
  // snapshot directories (names sort by time).
  const std::uintmax_t estimate = 11 * slot.frames.frames[0].image.sizeBytes();
  std::vector<fs::path> existing;
  for (const auto& e : fs::directory_iterator(root, ec))
    if (e.is_directory()) existing.push_back(e.path());
  std::sort(existing.begin(), existing.end());
  std::uintmax_t used = directorySize(root);
  for (const auto& old : existing) {
    if (used + estimate <= config.snapshots.quota_bytes) break;
    const std::uintmax_t size = directorySize(old);
    fs::remove_all(old, ec);
    used = used > size ? used - size : 0;
  }
  if (used + estimate > config.snapshots.quota_bytes)
    throw std::runtime_error("snapshot: quota of " + std::to_string(config.snapshots.quota_bytes >> 20) + " MB in " +
                             root.string() + " is too small for one snapshot");

  char stamp[32];
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
  const fs::path dir = root / (std::string(stamp) + "-cycle" + std::to_string(result.request.cycle_id));
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("snapshot: cannot create " + dir.string() + ": " + ec.message());
  try {
    writeSnapshotFiles(dir, config, job, stage, reason);
  } catch (...) {
    fs::remove_all(dir, ec);  // no half snapshot is left to be taken for a whole one
    throw;
  }
  return dir.string();
}

namespace {

// The overlay's input: the candidates the cycle reported, with their part names.
vision::PipelineResult candidatesOf(const CycleResult& result, const VisionStage& stage) {
  vision::PipelineResult out;
  const auto parts = stage.parts();
  for (int i = 0; i < result.candidate_count; ++i) {
    const CandidateOut& c = result.candidates[static_cast<std::size_t>(i)];
    vision::PoseCandidate p;
    p.obj_id = c.obj_id;
    for (const auto& [id, name] : parts)
      if (id == c.obj_id) p.part = name;
    p.R_m2c = c.R_cam;
    p.t_m2c_mm = c.t_cam_mm;
    p.score = c.score;
    p.box = c.box;
    out.candidates.push_back(p);
  }
  return out;
}

void writeSnapshotFiles(const fs::path& dir, const DaemonConfig& config, const RetainedJob& job, const VisionStage* stage,
                        const char* reason) {
  const FrameSlot& slot = job.slot();
  const CycleResult& result = job.result();
  if (slot.ok) {
    for (int k = 0; k < hal::kLedCount; ++k) writePng(dir / ("flash" + std::to_string(k) + ".png"), slot.mfc.flash[static_cast<std::size_t>(k)]);
    writePng(dir / "ambient.png", slot.mfc.ambient);
    if (result.error == CycleError::None && stage) {
      if (const cv::Mat1b* edges = job.edges()) writePng(dir / "edges.png", *edges);
      // Overlay on the brightest-flash composite, where every outline is lit.
      cv::Mat composite = slot.mfc.flash[0].clone();
      for (int k = 1; k < hal::kLedCount; ++k) cv::max(composite, cv::Mat(slot.mfc.flash[static_cast<std::size_t>(k)]), composite);
      writePng(dir / "overlay.png", stage->overlay(cv::Mat1b(composite), candidatesOf(result, *stage)));
    }
  }
  CycleResult withDir = result;
  copyMessage(withDir.snapshot_dir, sizeof withDir.snapshot_dir, dir.c_str());
  nlohmann::json j = resultJson(withDir, config);
  j["snapshot_reason"] = reason;
  std::ofstream out(dir / "result.json");
  out << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
  // close() flushes: a full disk shows here, not in the << above.
  out.close();
  if (out.fail()) throw std::runtime_error("snapshot: " + writeFailure(dir / "result.json"));
}

}  // namespace

}  // namespace mfcd::daemon
