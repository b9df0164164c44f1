#pragma once
// Non-maximum suppression over search candidates: keep the cheapest hypothesis of every group
// whose placed templates overlap significantly (paper Sec. 5.2).
#include <vector>

#include <opencv2/core/types.hpp>

#include "vision/search/exhaustive_search.hpp"

namespace mfcd::vision {

// Axis-aligned box of the template's pixels at the candidate's translation.
cv::Rect2d placedBox(const OrientedTemplate& t, const Candidate& c);

// `candidates` sorted best first. Keeps a candidate when its box overlaps every kept box by
// IoU <= maxIoU; stops after maxKeep. Returns the kept candidates, best first.
std::vector<Candidate> nonMaximumSuppression(const std::vector<Candidate>& candidates,
                                             const std::vector<OrientedTemplate>& templates, double maxIoU,
                                             size_t maxKeep);

}  // namespace mfcd::vision
