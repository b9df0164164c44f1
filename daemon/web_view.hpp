#pragma once
// The daemon's side of the web operator view (WebServer's WebData): JSON copies of what the main
// thread published (status, last cycle, statistics), the snapshot directory, and the last
// cycle's images from the cell's LatestFrame, encoded as PNG on the web server's threads.
// Thread-safety: the main thread calls update() and set_cell(); the web server's threads call the
// WebData functions. The vision worker only ever writes the LatestFrame (lock-free); the locks
// here are between the main thread and the web threads, never on the frame path.
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/latest_frame.hpp"
#include "daemon/web_server.hpp"
#include "vision/camera/camera.hpp"

namespace mfcd::daemon {

class WebView final : public WebData {
 public:
  explicit WebView(std::filesystem::path snapshot_directory);

  // --- main thread ---
  void update(nlohmann::json status, nlohmann::json last, nlohmann::json stats);
  // The running cell's frames (nullptr while there is none, e.g. during a reload), its part names
  // and camera (for the overlay).
  void set_cell(LatestFrame* frames, std::vector<std::pair<int, std::string>> parts, vision::CameraConfig camera);

  // --- WebData (web server threads) ---
  nlohmann::json status() override;
  nlohmann::json last_cycle() override;
  nlohmann::json stats() override;
  nlohmann::json snapshots() override;
  bool image_png(const std::string& name, std::string& png) override;
  std::filesystem::path snapshot_file(const std::string& snapshot, const std::string& file) override;

 private:
  const std::filesystem::path snapshot_dir_;
  std::mutex json_mutex_;
  nlohmann::json status_, last_, stats_;

  std::mutex frame_mutex_;  // the LatestFrame's one reader at a time, and the PNG cache
  LatestFrame* frames_ = nullptr;
  std::vector<std::pair<int, std::string>> parts_;
  vision::CameraConfig camera_;
  std::uint64_t cached_cycle_ = 0;
  std::map<std::string, std::string> cache_;  // name -> PNG of cached_cycle_
};

}  // namespace mfcd::daemon
