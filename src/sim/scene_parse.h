#pragma once
// Parsers for the parts of a scene file shared by objects, furniture and union parts: poses,
// materials and shapes (private to sim/; the top level is in scene_loader.cpp).

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/geometry/se3.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/sim/shape.h"
#include "dqo_map/sim/texture.h"
#include "yaml_reader.h"

namespace dqo::sim::detail {

struct ParseContext {
  std::string file;      // for messages
  std::string base_dir;  // relative paths (meshes, trajectories) start here
  const MeshLoader* loader = nullptr;
  std::map<std::string, ShapePtr> mesh_cache;  // a mesh file used twice is loaded once
};

std::string resolve_path(const ParseContext& ctx, const std::string& path);

// {position: [x, y, z], and at most one of rpy_deg: [r, p, y], rpy: [...] (radians),
// quaternion: [x, y, z, w]}; R = Rz(yaw) Ry(pitch) Rx(roll).
SE3 parse_pose(const YAML::Node& node, ParseContext& ctx, const std::string& context);

// {colour: [r, g, b]} or {texture: checker|noise|stripes|wood, colour_a, colour_b, scale, ...}.
// `default_seed` seeds noise and wood unless the material gives its own.
Texture parse_material(const YAML::Node& node, ParseContext& ctx, const std::string& context,
                       uint32_t default_seed);

struct ParsedShape {
  ShapePtr shape;
  // For a union: each part's own material, if it has one.
  std::vector<std::optional<Texture>> part_materials;
};

// {type: box|quad|ellipsoid|sphere|cylinder|superquadric|lathe|extrusion|mesh|union, ...}.
ParsedShape parse_shape(const YAML::Node& node, ParseContext& ctx, const std::string& context,
                        uint32_t default_seed, bool allow_union = true);

}  // namespace dqo::sim::detail
