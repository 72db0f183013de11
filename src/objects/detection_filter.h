#pragma once
// The detection filter of METHOD.md §2.1 (VOOM's): every input detection gets a verdict, the ones
// that pass keep theirs empty (std::nullopt) and go on to association.
#include <optional>
#include <vector>
#include "dqo_map/common/dataset.h"
#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

struct FilteredDetections {
  // [input detection]: nullopt when it passed, otherwise why it was dropped.
  std::vector<std::optional<DetectionVerdict>> rejected;
  std::vector<int> kept;  // indices of the input detections that passed, ascending
};

// Checks, in order: a finite box of positive size that overlaps the image (kInvalid), score,
// area, border; then the max_detections best-scoring survivors (kOverLimit for the rest); then
// duplicates, best score first (non-maximum suppression with a class-dependent IoU).
FilteredDetections filter_detections(const std::vector<Detection2d>& detections, int image_width,
                                     int image_height, const DetectionFilterParams& params);

}  // namespace dqo::objects
