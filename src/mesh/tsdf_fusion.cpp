// TSDF fusion through Open3D's ScalableTSDFVolume; Open3D's headers stay in this file.
#include "dqo_map/mesh/tsdf_fusion.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <memory>

#include <open3d/camera/PinholeCameraIntrinsic.h>
#include <open3d/geometry/Image.h>
#include <open3d/geometry/RGBDImage.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/pipelines/integration/ScalableTSDFVolume.h>

namespace dqo::mesh {

namespace {

namespace o3d = open3d;

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

bool finite(double x) { return std::isfinite(x); }

bool check_view(const FusionView& view, size_t k, std::string* error) {
  const std::string name = "fusion view " + std::to_string(k) + ": ";
  const PinholeCamera& cam = view.camera;
  if (cam.width <= 0 || cam.height <= 0) {
    return fail(error, name + "camera has no pixels (" + std::to_string(cam.width) + "x" +
                           std::to_string(cam.height) + ")");
  }
  if (!(cam.fx > 0.0) || !(cam.fy > 0.0) || !finite(cam.fx) || !finite(cam.fy) ||
      !finite(cam.cx) || !finite(cam.cy)) {
    return fail(error, name + "camera intrinsics are not positive and finite");
  }
  const size_t pixels = static_cast<size_t>(cam.width) * static_cast<size_t>(cam.height);
  if (view.depth.size() != pixels) {
    return fail(error, name + "depth has " + std::to_string(view.depth.size()) +
                           " values for a " + std::to_string(cam.width) + "x" +
                           std::to_string(cam.height) + " camera");
  }
  if (view.rgb.size() != 3 * pixels) {
    return fail(error, name + "rgb has " + std::to_string(view.rgb.size()) + " values, expected " +
                           std::to_string(3 * pixels) + " (3 per pixel)");
  }
  if (!view.T_wc.translation().allFinite() || !view.T_wc.quaternion().coeffs().allFinite()) {
    return fail(error, name + "pose is not finite");
  }
  return true;
}

// The view as Open3D's RGBD image: colour quantised to 8 bits (Open3D's RGB8 colour volume),
// depth as float metres with invalid and too-far values set to 0 (Open3D's "no measurement";
// for float depth images Integrate applies no truncation of its own). Returns the number of
// valid depth pixels.
size_t to_rgbd(const FusionView& view, double depth_max, o3d::geometry::RGBDImage* rgbd) {
  const int w = view.camera.width;
  const int h = view.camera.height;
  rgbd->color_.Prepare(w, h, 3, 1);
  rgbd->depth_.Prepare(w, h, 1, 4);
  uint8_t* colour = rgbd->color_.data_.data();
  float* depth = reinterpret_cast<float*>(rgbd->depth_.data_.data());
  const size_t pixels = static_cast<size_t>(w) * h;
  size_t valid = 0;
  for (size_t i = 0; i < pixels; ++i) {
    for (int c = 0; c < 3; ++c) {
      float v = view.rgb[3 * i + c];
      if (!std::isfinite(v)) v = 0.0f;
      colour[3 * i + c] = static_cast<uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
    }
    const float d = view.depth[i];
    if (std::isfinite(d) && d > 0.0f && d <= depth_max) {
      depth[i] = d;
      ++valid;
    } else {
      depth[i] = 0.0f;
    }
  }
  return valid;
}

TriangleMesh from_open3d(const o3d::geometry::TriangleMesh& m) {
  TriangleMesh out;
  out.vertices = m.vertices_;
  out.triangles.reserve(m.triangles_.size());
  for (const Eigen::Vector3i& t : m.triangles_) out.triangles.push_back({t[0], t[1], t[2]});
  if (m.HasVertexColors()) out.colours = m.vertex_colors_;
  return out;
}

// Removes the triangles with a vertex outside the box, then the vertices no triangle uses.
void crop_to_box(const OrientedBox& box, o3d::geometry::TriangleMesh* m) {
  const Eigen::Matrix3d R_bw = box.rotation.transpose();
  // The same relative tolerance as geometry's contains(), without its per-call overhead.
  const double tolerance = 1e-12 * std::max(1.0, box.half_extents.maxCoeff());
  std::vector<bool> inside(m->vertices_.size());
  for (size_t i = 0; i < m->vertices_.size(); ++i) {
    const Eigen::Vector3d p_b = R_bw * (m->vertices_[i] - box.centre);
    inside[i] = (p_b.cwiseAbs() - box.half_extents).maxCoeff() <= tolerance;
  }
  std::vector<bool> remove(m->triangles_.size());
  for (size_t t = 0; t < m->triangles_.size(); ++t) {
    const Eigen::Vector3i& tri = m->triangles_[t];
    remove[t] = !(inside[tri[0]] && inside[tri[1]] && inside[tri[2]]);
  }
  m->RemoveTrianglesByMask(remove);
  m->RemoveUnreferencedVertices();
}

// Keeps the connected component (triangles sharing edges) of largest area.
void keep_largest_component(o3d::geometry::TriangleMesh* m) {
  if (m->triangles_.empty()) return;
  const auto [cluster_of_triangle, cluster_triangles, cluster_area] =
      m->ClusterConnectedTriangles();
  (void)cluster_triangles;
  if (cluster_area.size() <= 1) return;
  const int largest = static_cast<int>(
      std::max_element(cluster_area.begin(), cluster_area.end()) - cluster_area.begin());
  std::vector<bool> remove(m->triangles_.size());
  for (size_t t = 0; t < remove.size(); ++t) remove[t] = cluster_of_triangle[t] != largest;
  m->RemoveTrianglesByMask(remove);
  m->RemoveUnreferencedVertices();
}

// Integrates the views and extracts Open3D's mesh; nullptr and *error on failure.
std::shared_ptr<o3d::geometry::TriangleMesh> fuse(const std::vector<FusionView>& views,
                                                  double voxel_size, const TsdfParams& params,
                                                  std::string* error) {
  if (views.empty()) {
    fail(error, "no views to fuse");
    return nullptr;
  }
  if (!(voxel_size > 0.0) || !finite(voxel_size)) {
    fail(error, "voxel size must be positive and finite (got " + std::to_string(voxel_size) + ")");
    return nullptr;
  }
  if (!(params.truncation_voxels > 0.0) || !finite(params.truncation_voxels)) {
    fail(error, "truncation_voxels must be positive and finite");
    return nullptr;
  }
  if (params.block_voxels < 1 || params.block_voxels > 256) {
    fail(error, "block_voxels must be in [1, 256] (got " + std::to_string(params.block_voxels) + ")");
    return nullptr;
  }
  if (!(params.depth_max > 0.0)) {
    fail(error, "depth_max must be positive");
    return nullptr;
  }
  for (size_t k = 0; k < views.size(); ++k) {
    if (!check_view(views[k], k, error)) return nullptr;
  }

  try {
    o3d::pipelines::integration::ScalableTSDFVolume volume(
        voxel_size, params.truncation_voxels * voxel_size,
        o3d::pipelines::integration::TSDFVolumeColorType::RGB8, params.block_voxels);
    size_t valid = 0;
    o3d::geometry::RGBDImage rgbd;
    for (const FusionView& view : views) {
      const size_t n = to_rgbd(view, params.depth_max, &rgbd);
      if (n == 0) continue;  // nothing to add, and Open3D would still walk the image
      valid += n;
      const PinholeCamera& cam = view.camera;
      const o3d::camera::PinholeCameraIntrinsic intrinsic(cam.width, cam.height, cam.fx, cam.fy,
                                                          cam.cx, cam.cy);
      // Open3D's extrinsic maps world to camera: T_cw.
      volume.Integrate(rgbd, intrinsic, view.T_wc.inverse().matrix());
    }
    if (valid == 0) {
      fail(error, "no surface fused (no view has a valid depth)");
      return nullptr;
    }
    return volume.ExtractTriangleMesh();
  } catch (const std::exception& e) {
    // Open3D reports bad input and allocation failures by throwing from LogError.
    fail(error, std::string("TSDF fusion failed: ") + e.what());
    return nullptr;
  }
}

}  // namespace

double object_voxel_size(const OrientedBox& object_box, const TsdfParams& params) {
  const double largest_extent = 2.0 * object_box.half_extents.maxCoeff();
  const double voxel = params.voxels_across > 0.0 ? largest_extent / params.voxels_across : 0.0;
  // max then min rather than std::clamp, which is undefined when min_voxel > max_voxel.
  return std::min(std::max(voxel, params.min_voxel), params.max_voxel);
}

OrientedBox object_crop_box(const OrientedBox& object_box, const TsdfParams& params) {
  OrientedBox crop = object_box;
  const double margin = std::max(params.crop_margin * 2.0 * object_box.half_extents.maxCoeff(),
                                 2.0 * object_voxel_size(object_box, params));
  crop.half_extents.array() += margin;
  return crop;
}

std::optional<TriangleMesh> fuse_views(const std::vector<FusionView>& views, double voxel_size,
                                       const TsdfParams& params, std::string* error) {
  const auto fused = fuse(views, voxel_size, params, error);
  if (!fused) return std::nullopt;
  if (fused->triangles_.empty()) {
    fail(error, "no surface fused (the TSDF holds no zero crossing)");
    return std::nullopt;
  }
  return from_open3d(*fused);
}

std::optional<TriangleMesh> fuse_object(const std::vector<FusionView>& views,
                                        const OrientedBox& object_box, const TsdfParams& params,
                                        std::string* error) {
  if (!object_box.centre.allFinite() || !object_box.rotation.allFinite() ||
      !object_box.half_extents.allFinite() || (object_box.half_extents.array() < 0.0).any()) {
    fail(error, "object box is not finite or has a negative half extent");
    return std::nullopt;
  }
  const double voxel = object_voxel_size(object_box, params);
  const auto fused = fuse(views, voxel, params, error);
  if (!fused) return std::nullopt;
  if (params.crop_margin >= 0.0) crop_to_box(object_crop_box(object_box, params), fused.get());
  if (params.largest_component) keep_largest_component(fused.get());
  if (fused->triangles_.empty()) {
    fail(error, "no surface fused inside the object's box");
    return std::nullopt;
  }
  return from_open3d(*fused);
}

}  // namespace dqo::mesh
