#pragma once
// The figures of a finished offline run against the dataset's ground truth (METHOD.md §6):
// trajectory (ATE), objects (found / spurious, 3D IoU, 2D IoU, CDE) and per-object reconstruction
// (Accuracy, Completion, Completion ratios) — what dqo_map_offline writes to metrics.json.

#include <optional>
#include <string>
#include <vector>

#include "dqo_map/eval/ate.h"
#include "dqo_map/eval/object_metrics.h"
#include "dqo_map/mapping/mapping_types.h"
#include "dqo_map/mesh/object_recon.h"
#include "dqo_map/system/offline_mapping.h"

namespace dqo::system {

struct OfflineMetrics {
  std::optional<eval::AteResult> ate;        // nullopt without ground-truth poses
  std::optional<eval::ObjectMetrics> objects;  // nullopt without ground-truth objects
  std::optional<mesh::ObjectReconTable> recon; // nullopt without ground-truth meshes
  std::vector<std::string> notes;            // why a part is missing
};

// `objects`: the run's objects (their reported boxes are compared); `meshes`: an object's mesh by
// ID (nullopt when it has none); `views`: the keyframes, for the 2D IoU.
OfflineMetrics evaluate_offline_run(const OfflineResult& run,
                                    const std::vector<mapping::ObjectRecord>& objects,
                                    const std::vector<mapping::KeyframePose>& views,
                                    const DatasetInfo& info, const mesh::EstimatedMeshFn& meshes,
                                    const mesh::ReconParams& recon_params = {});

// metrics.json: {"ate": {...}, "objects": {...}, "reconstruction": {"objects": [...], "mean": {...}}}
std::string metrics_json(const OfflineMetrics& metrics);

}  // namespace dqo::system
