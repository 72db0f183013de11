#include "scene_parse.h"

#include <cmath>
#include <filesystem>
#include <memory>

#include "dqo_map/sim/mesh_shape.h"
#include "dqo_map/sim/primitives.h"
#include "dqo_map/sim/procedural_mesh.h"
#include "dqo_map/sim/union_shape.h"

namespace dqo::sim::detail {
namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3f colour_of(YamlMap& m, const std::string& key) {
  const YAML::Node v = m.required(key);
  const Eigen::VectorXd c = as_vector(v, 3, m.file(), m.what(key));
  if ((c.array() < 0.0).any() || (c.array() > 1.0).any()) {
    fail_at(m.file(), v, m.what(key) + " must be [r, g, b] with each value in [0, 1]");
  }
  return c.cast<float>();
}

Eigen::Vector3d positive_vec3(YamlMap& m, const std::string& key) {
  const Eigen::Vector3d v = m.vec3(key);
  if ((v.array() <= 0.0).any()) m.fail_key(key, m.what(key) + " must be positive");
  return v;
}

double positive(YamlMap& m, const std::string& key) {
  const double v = m.number(key);
  if (!(v > 0.0)) m.fail_key(key, m.what(key) + " must be positive");
  return v;
}

int segments_of(YamlMap& m, int fallback) {
  const int s = m.integer_or("segments", fallback);
  if (s < 8 || s > 1024) m.fail_key("segments", m.what("segments") + " must lie in [8, 1024]");
  return s;
}

ShapePtr load_mesh(YamlMap& m, ParseContext& ctx) {
  const YAML::Node file_node = m.required("file");
  const std::string file = as_string(file_node, ctx.file, m.what("file"));
  const double crease = m.number_in_or("crease_deg", 0.0, 180.0, 40.0);
  const std::string path = resolve_path(ctx, file);
  const std::string key = path + "#" + std::to_string(crease);
  if (const auto it = ctx.mesh_cache.find(key); it != ctx.mesh_cache.end()) return it->second;
  if (ctx.loader == nullptr || !*ctx.loader) {
    fail_at(ctx.file, file_node,
            m.context() + " uses the mesh file '" + file +
                "' but no mesh loader was given (io/ provides one for PLY and OBJ)");
  }
  std::string err;
  std::optional<TriangleMesh> mesh = (*ctx.loader)(path, &err);
  if (!mesh) fail_at(ctx.file, file_node, "cannot load the mesh '" + path + "': " + err);
  if (mesh->empty()) fail_at(ctx.file, file_node, "the mesh '" + path + "' has no triangles");
  for (const auto& t : mesh->triangles) {
    for (const int i : t) {
      if (i < 0 || i >= static_cast<int>(mesh->vertices.size())) {
        fail_at(ctx.file, file_node,
                "the mesh '" + path + "' has a triangle with a bad vertex index");
      }
    }
  }
  auto shape = std::make_shared<MeshShape>(std::move(*mesh), "mesh", crease);
  ctx.mesh_cache[key] = shape;
  return shape;
}

std::vector<Eigen::Vector2d> points2(YamlMap& m, const std::string& key, size_t min_count) {
  std::vector<Eigen::Vector2d> out;
  for (const auto& p : as_points(m.required(key), 2, min_count, m.file(), m.what(key))) {
    out.emplace_back(p[0], p[1]);
  }
  return out;
}

}  // namespace

std::string resolve_path(const ParseContext& ctx, const std::string& path) {
  const std::filesystem::path p(path);
  if (p.is_absolute() || ctx.base_dir.empty()) return p.lexically_normal().string();
  return (std::filesystem::path(ctx.base_dir) / p).lexically_normal().string();
}

SE3 parse_pose(const YAML::Node& node, ParseContext& ctx, const std::string& context) {
  YamlMap m(node, ctx.file, context);
  const Eigen::Vector3d position = m.vec3("position");
  int given = 0;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  for (const char* key : {"rpy_deg", "rpy"}) {
    if (!m.has(key)) {
      m.optional(key);
      continue;
    }
    ++given;
    Eigen::Vector3d rpy = m.vec3(key);
    if (std::string(key) == "rpy_deg") rpy *= kPi / 180.0;
    q = Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
        Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
        Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX());
  }
  if (m.has("quaternion")) {
    ++given;
    const YAML::Node v = m.required("quaternion");
    const Eigen::VectorXd x = as_vector(v, 4, ctx.file, m.what("quaternion") + " [x, y, z, w]");
    q = Eigen::Quaterniond(x[3], x[0], x[1], x[2]);
    if (std::abs(q.norm() - 1.0) > 1e-3)
      fail_at(ctx.file, v, m.what("quaternion") + " must have unit length");
  } else {
    m.optional("quaternion");
  }
  if (given > 1) m.fail("give at most one of rpy_deg, rpy and quaternion in " + context);
  m.finish();
  return SE3(q, position);
}

Texture parse_material(const YAML::Node& node, ParseContext& ctx, const std::string& context,
                       uint32_t default_seed) {
  YamlMap m(node, ctx.file, context);
  Texture tex;
  const std::string type = m.string_or("texture", "uniform");
  if (!texture_type_from_string(type, &tex.type)) {
    m.fail_key("texture", "unknown texture '" + type + "' in " + context +
                              " (uniform, checker, noise, stripes, wood)");
  }
  tex.seed =
      static_cast<uint32_t>(m.integer_or("seed", static_cast<int>(default_seed & 0x7fffffff)));
  if (tex.type == TextureType::kUniform) {
    tex.colour_a = tex.colour_b = colour_of(m, "colour");
    m.finish();
    return tex;
  }
  tex.colour_a = colour_of(m, "colour_a");
  tex.colour_b = colour_of(m, "colour_b");
  tex.scale = positive(m, "scale");
  if (tex.type == TextureType::kNoise || tex.type == TextureType::kWood) {
    tex.octaves =
        static_cast<int>(m.number_in_or("octaves", 1, 8, tex.type == TextureType::kWood ? 2 : 3));
  }
  if (tex.type == TextureType::kNoise) tex.contrast = m.number_in_or("contrast", 0.0, 10.0, 1.0);
  if (tex.type == TextureType::kStripes) tex.softness = m.number_in_or("softness", 0.0, 1.0, 0.1);
  if (tex.type == TextureType::kStripes || tex.type == TextureType::kWood) {
    const Eigen::Vector3d axis = m.vec3_or("axis", Eigen::Vector3d::UnitZ());
    if (axis.norm() < 1e-9) m.fail_key("axis", m.what("axis") + " must not be zero");
    tex.axis = axis.normalized();
  }
  m.finish();
  return tex;
}

ParsedShape parse_shape(const YAML::Node& node, ParseContext& ctx, const std::string& context,
                        uint32_t default_seed, bool allow_union) {
  YamlMap m(node, ctx.file, context);
  const std::string type = m.string("type");
  ParsedShape out;
  if (type == "box") {
    out.shape = std::make_shared<Box>(positive_vec3(m, "size"));
  } else if (type == "quad") {
    const Eigen::Vector2d size = m.vec2("size");
    if ((size.array() <= 0.0).any()) m.fail_key("size", m.what("size") + " must be positive");
    out.shape = std::make_shared<Quad>(size);
  } else if (type == "ellipsoid") {
    const Eigen::Vector3d radii = positive_vec3(m, "radii");
    out.shape = std::make_shared<Ellipsoid>(radii, segments_of(m, 128));
  } else if (type == "sphere") {
    const double r = positive(m, "radius");
    out.shape = std::make_shared<Ellipsoid>(Eigen::Vector3d::Constant(r), segments_of(m, 128));
  } else if (type == "cylinder") {
    const double r = positive(m, "radius");
    const double h = positive(m, "height");
    out.shape = std::make_shared<Cylinder>(r, h, segments_of(m, 128));
  } else if (type == "superquadric") {
    const Eigen::Vector3d radii = positive_vec3(m, "radii");
    const YAML::Node ev = m.required("exponents");
    const Eigen::VectorXd e = as_vector(ev, 2, ctx.file, m.what("exponents") + " [e1, e2]");
    if ((e.array() < 0.1).any() || (e.array() > 4.0).any()) {
      fail_at(ctx.file, ev, m.what("exponents") + " must lie in [0.1, 4]");
    }
    const int segments = segments_of(m, 96);
    out.shape = std::make_shared<MeshShape>(make_superquadric_mesh(radii, e[0], e[1], segments),
                                            "superquadric");
  } else if (type == "lathe") {
    const YAML::Node pv = m.optional("profile");
    std::vector<Eigen::Vector2d> profile = points2(m, "profile", 3);
    if (profile.front().x() != 0.0 || profile.back().x() != 0.0) {
      fail_at(
          ctx.file, pv,
          m.what("profile") + " must start and end on the axis (r = 0) so the surface is closed");
    }
    for (const auto& p : profile) {
      if (p.x() < 0.0)
        fail_at(ctx.file, pv, m.what("profile") + " must have r >= 0 (points are [r, z])");
    }
    const int smooth = static_cast<int>(m.number_in_or("smooth", 0, 16, 0));
    const int segments = segments_of(m, 96);
    out.shape = std::make_shared<MeshShape>(
        make_lathe_mesh(smooth_profile(profile, smooth), segments), "lathe");
  } else if (type == "extrusion") {
    const YAML::Node pv = m.optional("polygon");
    const std::vector<Eigen::Vector2d> polygon = points2(m, "polygon", 3);
    const double depth = positive(m, "depth");
    TriangleMesh mesh = make_extrusion_mesh(polygon, depth);
    if (mesh.empty()) fail_at(ctx.file, pv, m.what("polygon") + " has no area");
    out.shape = std::make_shared<MeshShape>(std::move(mesh), "extrusion");
  } else if (type == "mesh") {
    out.shape = load_mesh(m, ctx);
  } else if (type == "union") {
    if (!allow_union) m.fail_key("type", "a union part cannot itself be a union (" + context + ")");
    const YAML::Node parts = m.required("parts");
    if (!parts.IsSequence() || parts.size() == 0)
      fail_at(ctx.file, parts, m.what("parts") + " must be a non-empty list");
    std::vector<UnionPart> built;
    for (size_t i = 0; i < parts.size(); ++i) {
      const std::string pc = "part " + std::to_string(i) + " of " + context;
      YamlMap pm(parts[i], ctx.file, pc);
      UnionPart part;
      const YAML::Node pose = pm.optional("pose");
      part.T_up = pose.IsDefined() ? parse_pose(pose, ctx, "pose of " + pc) : SE3();
      part.shape = parse_shape(pm.required("shape"), ctx, "shape of " + pc,
                               default_seed + 7919u * static_cast<uint32_t>(i + 1), false)
                       .shape;
      const YAML::Node mat = pm.optional("material");
      out.part_materials.push_back(mat.IsDefined()
                                       ? std::optional<Texture>(parse_material(
                                             mat, ctx, "material of " + pc,
                                             default_seed + 31u * static_cast<uint32_t>(i + 1)))
                                       : std::nullopt);
      pm.finish();
      built.push_back(std::move(part));
    }
    out.shape = std::make_shared<UnionShape>(std::move(built));
  } else {
    m.fail_key("type", "unknown shape type '" + type + "' in " + context +
                           " (box, quad, ellipsoid, sphere, cylinder, superquadric, lathe, "
                           "extrusion, mesh, union)");
  }
  m.finish();
  return out;
}

}  // namespace dqo::sim::detail
