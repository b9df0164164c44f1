#pragma once
// BOP results CSV, the format the BOP toolkit's evaluation reads (BOP Challenge 2019 onwards,
// bop_toolkit_lib/inout.py load_bop_results): a header line, then one line per pose estimate
//   scene_id,im_id,obj_id,score,R,t,time
// R: the model-to-camera rotation, row-major, 9 numbers separated by spaces; t: the
// model-to-camera translation in mm, 3 numbers separated by spaces; time: seconds the method
// took for the whole image (the same on every line of the image; -1 when not measured).
// The toolkit takes the dataset and split from the file's name, METHOD_DATASET-SPLIT.csv
// (docs/datasets.md, "Scoring with the BOP toolkit").

#include <opencv2/core.hpp>

#include <optional>
#include <string>

namespace mfcd::vision {

inline constexpr const char* kBopResultsHeader = "scene_id,im_id,obj_id,score,R,t,time";

struct BopResult {
  int scene_id = 0, im_id = 0, obj_id = 0;
  double score = 0;                    // higher is better
  cv::Matx33d R = cv::Matx33d::eye();  // model to camera
  cv::Vec3d t_mm{0, 0, 0};             // model to camera, mm
  double time_s = -1;                  // the image's run time, seconds
};

// One line of the CSV, '\n'-terminated: R with 9 decimals, t with 4 (0.1 um), score with 6, time
// with 4. Throws std::invalid_argument naming the scene, image and object on a non-finite number
// (the toolkit would read it and score nonsense).
std::string bop_results_row(const BopResult& r);

// The parts the toolkit reads from a results file name (inout.parse_result_filename): the name
// up to its first '.' is METHOD_DATASET-SPLIT[-SPLITTYPE][_ID].
struct BopResultsName {
  std::string method, dataset, split, split_type;
};
// Parses `file`'s name (any folder is ignored) as the toolkit does; nullopt when the toolkit
// would fail on it: no '_', or no '-' in the part after the first '_', or an empty method,
// dataset, split or (after a second '-') split type.
std::optional<BopResultsName> parse_bop_results_name(const std::string& file);

}  // namespace mfcd::vision
