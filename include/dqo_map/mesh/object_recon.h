#pragma once
// The per-object reconstruction table of a run (the paper's object tables): every ground-truth
// object with the estimated object matched to it, its mesh evaluated against the ground-truth mesh
// cropped to the ground-truth box (evaluate_reconstruction), and the mean over the objects that
// have a mesh. Matching is the caller's (eval::evaluate_objects); meshes come through a callback,
// so this module needs neither the run's files nor the Gaussian map.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"
#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/mesh/recon_metrics.h"

namespace dqo::mesh {

// One estimated object matched to one ground-truth object.
struct ReconMatch {
  uint64_t est_id = 0;
  uint64_t gt_id = 0;
};

struct ObjectReconRow {
  uint64_t est_id = 0;  // 0: no estimate matched this ground-truth object
  uint64_t gt_id = 0;
  int class_id = 0;
  std::string class_name;
  bool has_mesh = false;  // metrics were computed (both meshes present, surface inside the box)
  std::string note;       // why not, when has_mesh is false
  ReconMetrics metrics;
};

struct ObjectReconTable {
  std::vector<ObjectReconRow> rows;  // one per ground-truth object, in ground-truth order
  // Means of the four figures over rows with has_mesh (zero when there are none); rec_points and
  // gt_points are the totals over those rows.
  ReconMetrics mean;
  int num_with_mesh = 0;
};

// Returns the estimated object's mesh, or nullopt when it has none.
using EstimatedMeshFn = std::function<std::optional<TriangleMesh>(uint64_t est_id)>;

// params.crop_box is replaced per object by that object's ground-truth box (vMAP's crop, scaled by
// params.crop_scale). Matches naming a ground-truth ID that is not in `ground_truth` are ignored;
// a ground-truth object matched twice keeps the first match.
ObjectReconTable evaluate_object_reconstructions(const std::vector<GtObject>& ground_truth,
                                                 const std::vector<ReconMatch>& matches,
                                                 const EstimatedMeshFn& estimated_mesh,
                                                 const ReconParams& params);

// The paper-style table, one line per ground-truth object (est id, GT id, class, Acc cm, Comp cm,
// ratio < 1 cm %, ratio < 5 cm %; objects without a match or mesh say so), then the mean row.
std::string format_recon_table(const ObjectReconTable& table);

}  // namespace dqo::mesh
