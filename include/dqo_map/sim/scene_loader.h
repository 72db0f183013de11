#pragma once
// Loads a scene from YAML (config/scenes/*.yaml; the format is documented in
// config/scenes/README.md), strictly: an unknown key, a missing field, a value of the wrong type or
// out of range, an unknown class or texture, a mesh file that does not load — each is an error
// whose message starts with "FILE:LINE:COLUMN: " (1-based) and names the key. On error nothing is
// returned: no half-built scene.

#include <functional>
#include <optional>
#include <string>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/sim/scene.h"

namespace dqo::sim {

// Loads the triangle mesh of a `mesh: FILE` object (io/ provides one for PLY/OBJ through Open3D).
// Returns nullopt and sets *error when the file does not load. `path` is already resolved
// relative to the scene file's folder.
using MeshLoader =
    std::function<std::optional<TriangleMesh>(const std::string& path, std::string* error)>;

// What the command line changes in a scene as it is loaded (dqo_make_scene, dqo_map_offline).
struct SceneOverrides {
  // The simulated detector behaves as this profile whatever the file says about its rates
  // (noise/detections' profile, jitter, miss, confusion and false-positive keys); the file's
  // visibility thresholds and confusion groups stay. Nothing changes where the scene's noise is off.
  std::optional<DetectorProfile> detector_profile;
};

// `loader` may be empty: a scene without mesh files needs none; one with them is then an error.
std::optional<Scene> load_scene(const std::string& yaml_path, const MeshLoader& loader,
                                std::string* error, const SceneOverrides& overrides = {});

// The same from text in memory. `name_for_messages` stands for the file in messages, `base_dir`
// resolves relative paths (mesh and trajectory files).
std::optional<Scene> parse_scene(const std::string& yaml_text, const std::string& name_for_messages,
                                 const std::string& base_dir, const MeshLoader& loader,
                                 std::string* error, const SceneOverrides& overrides = {});

}  // namespace dqo::sim
