#include "dqo_map/mesh/object_recon.h"

#include <cstdio>
#include <map>

namespace dqo::mesh {

ObjectReconTable evaluate_object_reconstructions(const std::vector<GtObject>& ground_truth,
                                                 const std::vector<ReconMatch>& matches,
                                                 const EstimatedMeshFn& estimated_mesh,
                                                 const ReconParams& params) {
  std::map<uint64_t, uint64_t> est_of_gt;
  for (const ReconMatch& m : matches) est_of_gt.emplace(m.gt_id, m.est_id);

  ObjectReconTable table;
  for (const GtObject& gt : ground_truth) {
    ObjectReconRow row;
    row.gt_id = gt.id;
    row.class_id = gt.class_id;
    row.class_name = gt.class_name;
    const auto match = est_of_gt.find(gt.id);
    if (match == est_of_gt.end()) {
      row.note = "no match";
      table.rows.push_back(row);
      continue;
    }
    row.est_id = match->second;
    if (gt.mesh.empty()) {
      row.note = "no ground-truth mesh";
      table.rows.push_back(row);
      continue;
    }
    const std::optional<TriangleMesh> rec =
        estimated_mesh ? estimated_mesh(row.est_id) : std::nullopt;
    if (!rec || rec->empty()) {
      row.note = "no mesh";
      table.rows.push_back(row);
      continue;
    }
    ReconParams object_params = params;
    object_params.crop_box = gt.box;
    std::string error;
    const auto metrics = evaluate_reconstruction(*rec, gt.mesh, object_params, &error);
    if (!metrics) {
      row.note = error;
    } else {
      row.has_mesh = true;
      row.metrics = *metrics;
    }
    table.rows.push_back(row);
  }

  for (const ObjectReconRow& row : table.rows) {
    if (!row.has_mesh) continue;
    ++table.num_with_mesh;
    table.mean.accuracy_cm += row.metrics.accuracy_cm;
    table.mean.completion_cm += row.metrics.completion_cm;
    table.mean.comp_ratio_1cm += row.metrics.comp_ratio_1cm;
    table.mean.comp_ratio_5cm += row.metrics.comp_ratio_5cm;
    table.mean.rec_points += row.metrics.rec_points;
    table.mean.gt_points += row.metrics.gt_points;
  }
  if (table.num_with_mesh > 0) {
    const double n = table.num_with_mesh;
    table.mean.accuracy_cm /= n;
    table.mean.completion_cm /= n;
    table.mean.comp_ratio_1cm /= n;
    table.mean.comp_ratio_5cm /= n;
  }
  return table;
}

std::string format_recon_table(const ObjectReconTable& table) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-8s %-8s %-18s %8s %8s %10s %10s\n", "# est_id", "gt_id",
                "class", "acc_cm", "comp_cm", "ratio<1cm", "ratio<5cm");
  out += line;
  for (const ObjectReconRow& row : table.rows) {
    const std::string cls = std::to_string(row.class_id) +
                            (row.class_name.empty() ? "" : "(" + row.class_name + ")");
    const std::string est = row.est_id == 0 ? "-" : std::to_string(row.est_id);
    if (row.has_mesh) {
      std::snprintf(line, sizeof(line), "%-8s %-8llu %-18s %8.3f %8.3f %9.2f%% %9.2f%%\n",
                    est.c_str(), static_cast<unsigned long long>(row.gt_id), cls.c_str(),
                    row.metrics.accuracy_cm, row.metrics.completion_cm,
                    row.metrics.comp_ratio_1cm, row.metrics.comp_ratio_5cm);
      out += line;
    } else {
      std::snprintf(line, sizeof(line), "%-8s %-8llu %-18s ", est.c_str(),
                    static_cast<unsigned long long>(row.gt_id), cls.c_str());
      out += line;
      out += "(" + row.note + ")\n";
    }
  }
  if (table.num_with_mesh > 0) {
    std::snprintf(line, sizeof(line), "%-8s %-8s %-18s %8.3f %8.3f %9.2f%% %9.2f%%\n", "mean",
                  "-", ("over " + std::to_string(table.num_with_mesh) + " of " +
                        std::to_string(table.rows.size()))
                           .c_str(),
                  table.mean.accuracy_cm, table.mean.completion_cm, table.mean.comp_ratio_1cm,
                  table.mean.comp_ratio_5cm);
  } else {
    std::snprintf(line, sizeof(line), "mean     -        (no object with a mesh, of %zu)\n",
                  table.rows.size());
  }
  out += line;
  return out;
}

}  // namespace dqo::mesh
