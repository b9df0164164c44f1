// mfc-synth-2d: writes a synthetic 2-D matching problem for the demo and the CLI tests.
//   mfc-synth-2d --out DIR [--seed N] [--copies N]
// DIR/template_<name>.png   outline edge image of each part (white on black)
// DIR/query.png             grey scene: several rotated copies on a cluttered, noisy background
// DIR/truth.json            where each copy is (template, x, y, angle_deg)
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace {
struct Part {
  const char* name;
  std::vector<cv::Point2d> outline;  // px, around the origin
  double symmetryDeg;                // rotation that maps the outline onto itself (360: none)
};
const std::vector<Part> kParts{
    {"tnut", {{-40, -30}, {40, -30}, {40, -10}, {15, -10}, {15, 30}, {-15, 30}, {-15, -10}, {-40, -10}}, 360},
    {"bracket", {{-35, -35}, {35, -35}, {35, -20}, {-20, -20}, {-20, 35}, {-35, 35}}, 360},
    {"diamond", {{0, -45}, {28, 0}, {0, 45}, {-28, 0}}, 180},
};

std::vector<cv::Point> place(const std::vector<cv::Point2d>& shape, cv::Point2d at, double angle) {
  std::vector<cv::Point> out;
  const double c = std::cos(angle), s = std::sin(angle);
  for (const auto& p : shape) out.emplace_back(cvRound(at.x + c * p.x - s * p.y), cvRound(at.y + s * p.x + c * p.y));
  return out;
}
}  // namespace

int main(int argc, char** argv) {
  std::filesystem::path out;
  unsigned seed = 1;
  int copies = 4;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc)
      out = argv[++i];
    else if (a == "--seed" && i + 1 < argc)
      seed = static_cast<unsigned>(std::atoi(argv[++i]));
    else if (a == "--copies" && i + 1 < argc)
      copies = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: mfc-synth-2d --out DIR [--seed N] [--copies N]\n");
      return 2;
    }
  }
  if (out.empty() || copies < 1 || copies > 8) {
    std::fprintf(stderr, "usage: mfc-synth-2d --out DIR [--seed N] [--copies 1..8]\n");
    return 2;
  }
  std::filesystem::create_directories(out);
  for (const auto& part : kParts) {
    cv::Mat1b t(120, 120, uchar(0));
    cv::polylines(t, std::vector<std::vector<cv::Point>>{place(part.outline, {60, 60}, 0)}, true, 255, 1);
    cv::imwrite((out / ("template_" + std::string(part.name) + ".png")).string(), t);
  }
  std::mt19937 rng(seed);
  cv::Mat1b img(480, 640, uchar(70));
  std::uniform_int_distribution<int> ux(0, 639), uy(0, 479), ug(30, 140);
  for (int i = 0; i < 40; ++i) cv::line(img, {ux(rng), uy(rng)}, {ux(rng), uy(rng)}, ug(rng), 1, cv::LINE_AA);
  nlohmann::json truth = nlohmann::json::array();
  // Copies on a jittered grid so they do not overlap.
  const int cols = 4;
  std::uniform_real_distribution<double> jitter(-15, 15), angle(0, 360);
  for (int k = 0; k < copies; ++k) {
    const Part& part = kParts[k % kParts.size()];
    const cv::Point2d at(90 + (k % cols) * 150 + jitter(rng), 120 + (k / cols) * 230 + jitter(rng));
    // Angles on the 3-degree grid of q = 60 so the demo's best cost is near zero.
    const double deg = std::round(angle(rng) / 3.0) * 3.0;
    cv::fillPoly(img, std::vector<std::vector<cv::Point>>{place(part.outline, at, deg * CV_PI / 180)}, 190 + k * 7);
    truth.push_back({{"template", std::string("template_") + part.name},
                     {"x", at.x},
                     {"y", at.y},
                     {"angle_deg", deg},
                     {"symmetry_deg", part.symmetryDeg}});
  }
  cv::Mat1s noise(img.size()), tmp;
  cv::randn(noise, 0, 5);
  img.convertTo(tmp, CV_16S);
  tmp += noise;
  tmp.convertTo(img, CV_8U);
  cv::imwrite((out / "query.png").string(), img);
  std::ofstream(out / "truth.json") << truth.dump(2) << "\n";
  std::printf("wrote %s (query.png, truth.json, %zu templates)\n", out.c_str(), kParts.size());
  return 0;
}
