#pragma once
// A synthetic scene in memory: camera, lighting, background (room) and objects, trajectory, noise.
// Built by load_scene() from YAML (scene_loader.h) or by hand (tests).

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/sim/lighting.h"
#include "dqo_map/sim/noise.h"
#include "dqo_map/sim/shape.h"
#include "dqo_map/sim/texture.h"
#include "dqo_map/sim/trajectory.h"

namespace dqo::sim {

// A shape placed in the world: p_w = T_wo * (scale * p_o). Uniform scale only, so normals need no
// inverse-transpose and a ray keeps its parameter t in the object frame.
struct SceneObject {
  uint32_t id = 0;  // 0 = background (floor, walls, furniture): never in the instance image
  int class_id = 0;
  std::string class_name;
  SE3 T_wo;
  double scale = 1.0;
  ShapePtr shape;
  Texture material;
  // Material of union part i (Hit::part); parts without their own use `material`.
  std::vector<Texture> part_materials;

  const Texture& material_of(int part) const {
    return part >= 0 && part < static_cast<int>(part_materials.size()) ? part_materials[part]
                                                                       : material;
  }
};

struct Scene {
  std::string name;
  std::string source;  // the YAML file it came from, for messages
  PinholeCamera camera;
  double depth_scale = 1000.0;  // uint16 units per metre when written to disk
  double near = 0.01;           // metres: nothing nearer than this is seen
  Eigen::Vector3f background_colour = Eigen::Vector3f::Zero();  // where a ray hits nothing
  std::map<int, std::string> classes;                           // class ID -> name
  Lighting lighting;
  std::vector<SceneObject> background;     // id 0
  std::vector<SceneObject> objects;        // unique ids > 0
  std::vector<TrajectoryPose> trajectory;  // one per frame
  NoiseParams noise;
  uint64_t seed = 0;

  int num_frames() const { return static_cast<int>(trajectory.size()); }
};

// Every object's ground truth: the tight box of its surface mesh in its own frame, mapped to the
// world (so its axes are the object's), its class, and the mesh in world coordinates.
std::vector<GtObject> ground_truth_objects(const Scene& scene);

// Camera, depth scale, classes and the ground truth above.
DatasetInfo dataset_info(const Scene& scene);

// Empty string when the scene is consistent (non-zero unique object IDs, known classes, a camera,
// a shape on everything, at least one frame), otherwise what is wrong. load_scene() checks it;
// for scenes built by hand.
std::string validate_scene(const Scene& scene);

}  // namespace dqo::sim
