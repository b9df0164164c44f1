#include "daemon/web_view.hpp"

#include <algorithm>

#include <opencv2/imgcodecs.hpp>

#include "daemon/report.hpp"

namespace mfcd::daemon {

using nlohmann::json;

WebView::WebView(fs::path snapshot_directory) : snapshot_dir_(std::move(snapshot_directory)) {}

void WebView::update(json status, json last, json stats) {
  std::lock_guard lock(json_mutex_);
  status_ = std::move(status);
  last_ = std::move(last);
  stats_ = std::move(stats);
}

void WebView::set_cell(LatestFrame* frames, std::vector<std::pair<int, std::string>> parts,
                       vision::CameraConfig camera) {
  std::lock_guard lock(frame_mutex_);
  frames_ = frames;
  parts_ = std::move(parts);
  camera_ = std::move(camera);
  cached_cycle_ = 0;
  cache_.clear();
}

json WebView::status() {
  std::lock_guard lock(json_mutex_);
  return status_;
}

json WebView::last_cycle() {
  std::lock_guard lock(json_mutex_);
  return last_;
}

json WebView::stats() {
  std::lock_guard lock(json_mutex_);
  return stats_;
}

json WebView::snapshots() {
  json list = json::array();
  std::error_code ec;
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(snapshot_dir_, ec))
    if (e.is_directory(ec)) dirs.push_back(e.path());
  std::sort(dirs.rbegin(), dirs.rend());  // newest first (names start with the UTC time)
  for (const fs::path& d : dirs) {
    json files = json::array();
    for (const char* f : {"result.json", "overlay.png", "edges.png", "mfcd_replay.json", "camera.yaml", "mfcd.yaml"})
      if (fs::is_regular_file(d / f, ec)) files.push_back(f);
    list.push_back({{"name", d.filename().string()}, {"files", files}});
  }
  return {{"directory", snapshot_dir_.string()}, {"snapshots", list}};
}

bool WebView::image_png(const std::string& name, std::string& png) {
  std::lock_guard lock(frame_mutex_);
  const WebFrame* f = frames_ ? frames_->newest() : nullptr;
  if (!f) return false;
  if (f->result.request.cycle_id != cached_cycle_) {
    cached_cycle_ = f->result.request.cycle_id;
    cache_.clear();
  }
  if (auto it = cache_.find(name); it != cache_.end()) {
    png = it->second;
    return true;
  }
  cv::Mat image;
  if (name == "ambient")
    image = f->ambient;
  else if (name == "edges" && f->have_edges)
    image = f->edges;
  else if (name == "overlay")
    image = vision::draw_candidates(f->composite, overlay_candidates(f->result, parts_), camera_);
  if (image.empty()) return false;
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".png", image, bytes)) return false;
  png.assign(bytes.begin(), bytes.end());
  cache_[name] = png;
  return true;
}

fs::path WebView::snapshot_file(const std::string& snapshot, const std::string& file) {
  const fs::path p = snapshot_dir_ / snapshot / file;
  std::error_code ec;
  return fs::is_regular_file(p, ec) ? p : fs::path();
}

}  // namespace mfcd::daemon
