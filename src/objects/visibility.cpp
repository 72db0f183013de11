#include "visibility.h"

#include "dqo_map/geometry/conic.h"

namespace dqo::objects {

std::vector<VisibleObject> visible_objects(const std::vector<const DualQuadric*>& quadrics,
                                           const PinholeCamera& camera, const SE3& T_cw,
                                           const VisibilityParams& params,
                                           std::vector<int>* hidden) {
  std::vector<VisibleObject> in_view;
  for (size_t i = 0; i < quadrics.size(); ++i) {
    const auto projected = projected_box(*quadrics[i], camera, T_cw, params.near);
    if (!projected || projected->box.area() <= 0.0 ||
        projected->fraction_in_image < params.min_fraction_in_image) {
      continue;
    }
    VisibleObject v;
    v.index = static_cast<int>(i);
    v.box = projected->box;
    v.unclipped = projected->unclipped;
    v.depth = (T_cw * quadrics[i]->centre()).z();
    in_view.push_back(v);
  }
  std::vector<bool> occluded(in_view.size(), false);
  for (size_t a = 0; a < in_view.size(); ++a) {
    for (size_t b = a + 1; b < in_view.size(); ++b) {
      if (iou(in_view[a].box, in_view[b].box) > params.occlusion_iou) {
        occluded[in_view[a].depth <= in_view[b].depth ? b : a] = true;
      }
    }
  }
  std::vector<VisibleObject> out;
  for (size_t a = 0; a < in_view.size(); ++a) {
    if (occluded[a]) {
      if (hidden) hidden->push_back(in_view[a].index);
    } else {
      out.push_back(in_view[a]);
    }
  }
  return out;
}

}  // namespace dqo::objects
