#include "vision/search/nms.hpp"

namespace mfcd::vision {

cv::Rect2d placedBox(const OrientedTemplate& t, const Candidate& c) {
  return cv::Rect2d(c.tx + t.x0, c.ty + t.y0, t.x1 - t.x0 + 1, t.y1 - t.y0 + 1);
}

std::vector<Candidate> nonMaximumSuppression(const std::vector<Candidate>& candidates,
                                             const std::vector<OrientedTemplate>& templates, double maxIoU,
                                             size_t maxKeep) {
  std::vector<Candidate> kept;
  std::vector<cv::Rect2d> boxes;
  for (const auto& c : candidates) {
    if (kept.size() >= maxKeep) break;
    const cv::Rect2d b = placedBox(templates[c.oriented], c);
    bool ok = true;
    for (const auto& k : boxes) {
      const double inter = (b & k).area();
      const double uni = b.area() + k.area() - inter;
      if (uni > 0 && inter / uni > maxIoU) {
        ok = false;
        break;
      }
    }
    if (ok) {
      kept.push_back(c);
      boxes.push_back(b);
    }
  }
  return kept;
}

}  // namespace mfcd::vision
