#include "dqo_map/system/offline_metrics.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "dqo_map/system/offline_report.h"

namespace dqo::system {
namespace {

// A JSON number; NaN and infinities (no value) become null.
std::string num(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

std::string recon_json(const mesh::ReconMetrics& m) {
  return "{\"accuracy_cm\": " + num(m.accuracy_cm) + ", \"completion_cm\": " +
         num(m.completion_cm) + ", \"comp_ratio_1cm\": " + num(m.comp_ratio_1cm) +
         ", \"comp_ratio_5cm\": " + num(m.comp_ratio_5cm) + "}";
}

}  // namespace

OfflineMetrics evaluate_offline_run(const OfflineResult& run,
                                    const std::vector<mapping::ObjectRecord>& objects,
                                    const std::vector<mapping::KeyframePose>& views,
                                    const DatasetInfo& info, const mesh::EstimatedMeshFn& meshes,
                                    const mesh::ReconParams& recon_params) {
  OfflineMetrics m;
  if (run.ground_truth.size() >= 3 && run.trajectory.size() >= 3) {
    std::string error;
    m.ate = eval::compute_ate(run.trajectory, run.ground_truth, eval::AteParams(), &error);
    if (!m.ate) m.notes.push_back("ate: " + error);
  } else {
    m.notes.push_back("ate: fewer than 3 frames with ground-truth poses");
  }
  if (info.objects.empty()) {
    m.notes.push_back("objects: the dataset has no ground-truth objects");
    return m;
  }
  std::vector<eval::ObjectEstimate> est, gt;
  for (const mapping::ObjectRecord& o : objects) est.push_back({o.id, o.class_id, o.box});
  for (const GtObject& o : info.objects) gt.push_back({o.id, o.class_id, o.box});
  std::vector<eval::EvalView> eval_views;
  for (const mapping::KeyframePose& k : views) eval_views.push_back({k.camera, k.T_wc});
  m.objects = eval::evaluate_objects(est, gt, eval_views);

  bool any_mesh = false;
  for (const GtObject& o : info.objects) any_mesh = any_mesh || !o.mesh.empty();
  if (!any_mesh) {
    m.notes.push_back("reconstruction: the dataset has no ground-truth meshes");
    return m;
  }
  std::vector<mesh::ReconMatch> matches;
  for (const eval::ObjectMatch& match : m.objects->matches) {
    matches.push_back({match.est_id, match.gt_id});
  }
  m.recon = mesh::evaluate_object_reconstructions(info.objects, matches, meshes, recon_params);
  return m;
}

std::string metrics_json(const OfflineMetrics& m) {
  std::ostringstream out;
  out << "{\n";
  out << "  \"ate\": ";
  if (m.ate) {
    out << "{\"rmse_m\": " << num(m.ate->rmse_m) << ", \"mean_m\": " << num(m.ate->mean_m)
        << ", \"median_m\": " << num(m.ate->median_m) << ", \"max_m\": " << num(m.ate->max_m)
        << ", \"matched\": " << m.ate->matched << "}";
  } else {
    out << "null";
  }
  out << ",\n  \"objects\": ";
  if (m.objects) {
    const eval::ObjectMetrics& o = *m.objects;
    out << "{\"ground_truth\": " << o.num_gt << ", \"found\": " << o.num_matched
        << ", \"spurious\": " << o.num_spurious << ", \"mean_iou_3d\": " << num(o.mean_iou_3d)
        << ", \"mean_iou_2d\": " << num(o.mean_iou_2d) << ", \"mean_cde_m\": " << num(o.mean_cde)
        << ",\n    \"matches\": [";
    for (size_t i = 0; i < o.matches.size(); ++i) {
      const eval::ObjectMatch& x = o.matches[i];
      out << (i ? ",\n      " : "\n      ") << "{\"id\": " << x.est_id << ", \"gt_id\": " << x.gt_id
          << ", \"class_id\": " << x.class_id << ", \"iou_3d\": " << num(x.iou_3d)
          << ", \"iou_2d\": " << num(x.iou_2d) << ", \"cde_m\": " << num(x.centre_distance) << "}";
    }
    out << "]}";
  } else {
    out << "null";
  }
  out << ",\n  \"reconstruction\": ";
  if (m.recon) {
    out << "{\"objects\": [";
    for (size_t i = 0; i < m.recon->rows.size(); ++i) {
      const mesh::ObjectReconRow& r = m.recon->rows[i];
      out << (i ? ",\n      " : "\n      ") << "{\"id\": " << r.est_id << ", \"gt_id\": " << r.gt_id
          << ", \"class\": " << json_quoted(r.class_name) << ", \"has_mesh\": "
          << (r.has_mesh ? "true" : "false");
      if (r.has_mesh) {
        out << ", \"metrics\": " << recon_json(r.metrics);
      } else {
        out << ", \"note\": " << json_quoted(r.note);
      }
      out << "}";
    }
    out << "],\n    \"with_mesh\": " << m.recon->num_with_mesh
        << ", \"mean\": " << recon_json(m.recon->mean) << "}";
  } else {
    out << "null";
  }
  out << ",\n  \"notes\": [";
  for (size_t i = 0; i < m.notes.size(); ++i) out << (i ? ", " : "") << json_quoted(m.notes[i]);
  out << "]\n}\n";
  return out.str();
}

}  // namespace dqo::system
