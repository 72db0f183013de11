// render_mesh_views: each view holds the whole mesh, where a pinhole projection of its corners says.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "dqo_map/sim/mesh_views.h"
#include "dqo_map/sim/procedural_mesh.h"

namespace dqo::sim {
namespace {

TEST(MeshViews, BoxSilhouetteMatchesItsProjectedCorners) {
  const Eigen::Vector3d size(0.5, 0.3, 0.2), offset(1.0, 2.0, 0.5);
  TriangleMesh box = make_box_mesh(size);
  for (Eigen::Vector3d& v : box.vertices) v += offset;
  MeshViewParams params;
  params.size = 160;
  const std::vector<MeshView> views = render_mesh_views(box, params, 2);
  ASSERT_EQ(views.size(), params.azimuth_deg.size());
  for (const MeshView& view : views) {
    // The silhouette's bounds: pixels that are not the background.
    int u0 = params.size, v0 = params.size, u1 = -1, v1 = -1, hits = 0;
    for (int v = 0; v < params.size; ++v) {
      for (int u = 0; u < params.size; ++u) {
        const bool background = view.rgb.at(u, v, 0) == 255 && view.rgb.at(u, v, 1) == 255 && view.rgb.at(u, v, 2) == 255;
        if (background) continue;
        ++hits;
        u0 = std::min(u0, u), v0 = std::min(v0, v), u1 = std::max(u1, u), v1 = std::max(v1, v);
      }
    }
    EXPECT_EQ(hits, view.hit_pixels);
    // The corners' projections, independently of the ray caster: the box's silhouette is their
    // convex hull, so its bounds are theirs (to a pixel: a pixel is hit where its centre is).
    double pu0 = 1e9, pv0 = 1e9, pu1 = -1e9, pv1 = -1e9;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d corner = offset + 0.5 * Eigen::Vector3d((k & 1) ? size.x() : -size.x(),
                                                                   (k & 2) ? size.y() : -size.y(),
                                                                   (k & 4) ? size.z() : -size.z());
      const Eigen::Vector3d p_c = view.T_wc.inverse() * corner;
      ASSERT_GT(p_c.z(), 0.0);
      const Eigen::Vector2d uv = view.camera.project(p_c);
      pu0 = std::min(pu0, uv.x()), pv0 = std::min(pv0, uv.y()), pu1 = std::max(pu1, uv.x()), pv1 = std::max(pv1, uv.y());
    }
    EXPECT_NEAR(u0, pu0, 1.0);
    EXPECT_NEAR(v0, pv0, 1.0);
    EXPECT_NEAR(u1, pu1, 1.0);
    EXPECT_NEAR(v1, pv1, 1.0);
    // The whole box in frame, and large in it.
    EXPECT_GT(u0, 0);
    EXPECT_GT(v0, 0);
    EXPECT_LT(u1, params.size - 1);
    EXPECT_LT(v1, params.size - 1);
    EXPECT_GT(hits, params.size * params.size / 10);
  }
  EXPECT_TRUE(render_mesh_views(TriangleMesh(), params).empty());
}

}  // namespace
}  // namespace dqo::sim
