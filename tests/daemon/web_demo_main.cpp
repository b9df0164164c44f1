// A stand-in for mfcd behind the web operator view: WebServer with canned data whose cycle
// changes every second, and small PNGs drawn with OpenCV. For tests/daemon/web_browser_test.py,
// and for looking at the page by hand:
//
//   mfcd_web_demo --web-root <source>/web [--port N] [--bind ADDRESS] [--cycle-ms MS]
//
// --cycle-ms: a new cycle every MS milliseconds (1000). Prints "PORT <n>" once it listens (n is
// the kernel's choice without --port) and serves until its
// standard input closes (Ctrl-D, or the test ending). Snapshots live in a temporary directory that
// is removed on exit.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "daemon/web_server.hpp"

namespace fs = std::filesystem;
using mfcd::daemon::WebData;
using mfcd::daemon::WebServer;
using mfcd::daemon::WebSettings;
using nlohmann::json;

namespace {

constexpr double kBudgetMs = 150;
const char* const kParts[] = {"breaker", "diamond", "ellipse", "tnut", "knob", "wheel"};

// Cycle n's parts in a 320 x 240 image: four boxes that wander with n; candidate 1 is chosen.
std::vector<cv::Rect> boxes_of(std::uint64_t n) {
  std::vector<cv::Rect> boxes;
  for (int k = 0; k < 4; ++k) {
    const double phase = 0.7 * static_cast<double>(n) + 1.9 * k;
    boxes.emplace_back(30 + 70 * k + static_cast<int>(12 * std::sin(phase)),
                       60 + static_cast<int>(50 * std::cos(phase)), 44, 30 + 6 * k);
  }
  return boxes;
}

class DemoData final : public WebData {
 public:
  DemoData(fs::path snapshot_root, std::chrono::milliseconds period)
      : root_(std::move(snapshot_root)), period_(period) {}

  json status() override {
    const std::uint64_t n = cycle();
    json recipes = json::array(), parts = json::array();
    for (int id = 1; id <= 6; ++id) {
      recipes.push_back({{"id", id}, {"part", kParts[id - 1]}, {"obj_id", id}});
      parts.push_back({{"obj_id", id}, {"name", kParts[id - 1]}});
    }
    return {{"ok", true},
            {"version", "0.1.0-demo"},
            {"commit", "0123abc"},
            {"state", "ready"},
            {"ready", true},
            {"vision_ok", true},
            {"error_code", 0},
            {"recipe", 1},
            {"mode", "triggered"},
            {"cycle_budget_ms", kBudgetMs},
            {"camera", "simulated cell (mfcd_web_demo)"},
            {"modbus", {{"port", 1502}, {"clients", 1}, {"requests", 40 * n}, {"serving", true}}},
            {"recipes", recipes},
            {"parts", parts},
            {"cycles", n},
            {"overruns", n / 7},
            {"calibration", {{"active", false}}}};
  }

  json last_cycle() override {
    const std::uint64_t n = cycle();
    const double total = total_ms(n);
    json cands = json::array();
    for (int k = 0; k < 4; ++k) {
      cands.push_back({{"obj_id", 1 + (k + static_cast<int>(n)) % 6},
                       {"score", 0.92 - 0.11 * k},
                       {"cost_px", 1.2 + k},
                       {"ambiguous", k == 2},
                       {"t_cam_mm", {10.0 * k, -5.0 * k, 400.0 + k}}});
    }
    const json& chosen = cands[1];
    return {{"version", "0.1.0-demo"},
            {"cycle", n},
            {"job_id", (n * 3) % 65536},
            {"origin", "plc"},
            {"recipe", 1},
            {"mode", "pick"},
            {"error_code", 0},
            {"error", "none"},
            {"degraded", false},
            {"overrun", total > kBudgetMs},
            {"budget_ms", kBudgetMs},
            {"times_ms", {{"capture", 31.0}, {"vision", total - 40}, {"total", total}}},
            {"candidates", cands},
            {"chosen", 1},
            {"ranked", {1, 0, 3}},
            {"pick",
             {{"x", 412.5 + static_cast<double>(n % 10)},
              {"y", -88.25},
              {"z", 120.0},
              {"rx", 180.0},
              {"ry", 0.0},
              {"rz", 35.0 + static_cast<double>(n % 90)},
              {"score", chosen["score"]},
              {"obj_id", chosen["obj_id"]}}}};
  }

  json stats() override {
    const std::uint64_t n = cycle();
    return {{"cycles", n},
            {"overruns", n / 7},
            {"errors", 0},
            {"degraded", 0},
            {"picks", n},
            {"mean_ms", 104.0},
            {"budget_ms", kBudgetMs},
            {"pick_results",
             {{"ok", n / 2},
              {"missed", n / 11},
              {"unreachable", 0},
              {"collision", 0},
              {"dropped", n / 23},
              {"reported", n / 2 + n / 11 + n / 23}}},
            {"percentiles_ms", {{"total", {{"p50", 101.0}, {"p90", 138.5}, {"p99", 171.2}, {"max", 180.0}}}}}};
  }

  json snapshots() override {
    json list = json::array();
    for (const auto& entry : fs::directory_iterator(root_)) {
      json files = json::array();
      for (const auto& f : fs::directory_iterator(entry.path())) files.push_back(f.path().filename().string());
      list.push_back({{"name", entry.path().filename().string()}, {"files", files}});
    }
    return {{"directory", root_.string()}, {"snapshots", list}};
  }

  bool image_png(const std::string& name, std::string& png) override {
    const std::uint64_t n = cycle();
    std::lock_guard lock(mutex_);
    if (n != cached_cycle_) {
      for (const char* k : {"ambient", "edges", "overlay"}) cache_[k] = encode(draw(k, n));
      cached_cycle_ = n;
    }
    const auto it = cache_.find(name);
    if (it == cache_.end()) return false;
    png = it->second;
    return true;
  }

  fs::path snapshot_file(const std::string& snapshot, const std::string& file) override {
    const fs::path p = root_ / snapshot / file;
    return fs::is_regular_file(p) ? p : fs::path();
  }

  static cv::Mat draw(const std::string& what, std::uint64_t n) {
    cv::Mat1b grey(240, 320, static_cast<std::uint8_t>(110));
    for (int y = 0; y < grey.rows; ++y) grey.row(y).setTo(90 + y / 6);
    const std::vector<cv::Rect> boxes = boxes_of(n);
    for (const cv::Rect& b : boxes) cv::rectangle(grey, b, cv::Scalar(200), cv::FILLED);
    if (what == "ambient") return grey;
    cv::Mat1b edges;
    cv::Canny(grey, edges, 40, 120);
    if (what == "edges") return edges;
    cv::Mat3b overlay;
    cv::cvtColor(grey, overlay, cv::COLOR_GRAY2BGR);
    overlay.setTo(cv::Vec3b(255, 255, 0), edges);
    for (std::size_t k = 0; k < boxes.size(); ++k)
      cv::rectangle(overlay, boxes[k], k == 1 ? cv::Scalar(0, 200, 0) : cv::Scalar(0, 140, 255), k == 1 ? 3 : 1);
    cv::putText(overlay, "cycle " + std::to_string(n), {8, 228}, cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(255, 255, 255), 1);
    return overlay;
  }

 private:
  // One cycle per period since the start, the first being 1.
  std::uint64_t cycle() const {
    return 1 + static_cast<std::uint64_t>((std::chrono::steady_clock::now() - started_) / period_);
  }
  // Around 100 ms with some noise; every 7th cycle overruns the budget.
  static double total_ms(std::uint64_t n) {
    if (n % 7 == 0) return kBudgetMs + 20;
    return 100 + 25 * std::sin(0.9 * static_cast<double>(n)) + static_cast<double>((n * 37) % 11);
  }
  static std::string encode(const cv::Mat& image) {
    std::vector<std::uint8_t> bytes;
    cv::imencode(".png", image, bytes);
    return {bytes.begin(), bytes.end()};
  }

  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  fs::path root_;
  std::chrono::milliseconds period_;
  std::mutex mutex_;
  std::uint64_t cached_cycle_ = 0;
  std::map<std::string, std::string> cache_;
};

// Two snapshots, as mfcd names and fills them.
void make_snapshots(const fs::path& root) {
  for (const std::uint64_t n : {3u, 5u}) {
    const fs::path dir = root / ("20250101T12000" + std::to_string(n) + "Z-cycle" + std::to_string(n));
    fs::create_directories(dir);
    cv::imwrite((dir / "overlay.png").string(), DemoData::draw("overlay", n));
    cv::imwrite((dir / "edges.png").string(), DemoData::draw("edges", n));
    std::ofstream(dir / "result.json") << json{{"cycle", n}, {"error", "none"}}.dump(2) << "\n";
  }
}

int usage(const char* why) {
  std::fprintf(stderr,
               "mfcd_web_demo: %s\nusage: mfcd_web_demo --web-root DIR [--port N] [--bind ADDRESS] [--cycle-ms MS]\n",
               why);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  WebSettings settings;
  settings.enabled = true;
  settings.port = 0;
  fs::path web_root;
  std::chrono::milliseconds period(1000);
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (i + 1 >= argc) return usage(("missing value after " + arg).c_str());
    const std::string value = argv[++i];
    if (arg == "--web-root") {
      web_root = value;
    } else if (arg == "--port") {
      settings.port = static_cast<std::uint16_t>(std::atoi(value.c_str()));
    } else if (arg == "--bind") {
      settings.bind_address = value;
    } else if (arg == "--cycle-ms") {
      period = std::chrono::milliseconds(std::max(1, std::atoi(value.c_str())));
    } else {
      return usage(("unknown option " + arg).c_str());
    }
  }
  if (web_root.empty()) return usage("--web-root is required");

  std::string pattern = (fs::temp_directory_path() / "mfcd-web-demo-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) {
    std::perror("mfcd_web_demo: mkdtemp");
    return 1;
  }
  const fs::path snapshots = pattern;
  int rc = 0;
  try {
    make_snapshots(snapshots);
    DemoData data(snapshots, period);
    WebServer server(settings, data, web_root);
    server.start();
    std::printf("PORT %u\n", static_cast<unsigned>(server.port()));
    std::fflush(stdout);
    char buf[256];
    for (;;) {
      const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
      if (n == 0 || (n < 0 && errno != EINTR)) break;
    }
    server.stop();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mfcd_web_demo: %s\n", e.what());
    rc = 1;
  }
  std::error_code ec;
  fs::remove_all(snapshots, ec);
  return rc;
}
