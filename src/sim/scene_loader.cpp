#include "dqo_map/sim/scene_loader.h"

#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/sim/primitives.h"
#include "scene_parse.h"

namespace dqo::sim {
namespace detail {
namespace {

PinholeCamera parse_camera(const YAML::Node& node, ParseContext& ctx, Scene* scene) {
  YamlMap m(node, ctx.file, "camera");
  PinholeCamera cam;
  cam.width = static_cast<int>(m.number_in("width", 1, 16384));
  cam.height = static_cast<int>(m.number_in("height", 1, 16384));
  cam.fx = m.number_in("fx", 1e-3, 1e6);
  cam.fy = m.number_in("fy", 1e-3, 1e6);
  cam.cx = m.number("cx");
  cam.cy = m.number("cy");
  scene->depth_scale = m.number_in_or("depth_scale", 1e-3, 1e6, 1000.0);
  scene->near = m.number_in_or("near", 1e-4, 10.0, 0.01);
  m.finish();
  return cam;
}

void parse_classes(const YAML::Node& node, ParseContext& ctx, Scene* scene) {
  if (!node.IsSequence() || node.size() == 0) {
    fail_at(ctx.file, node, "'classes' must be a non-empty list of {id, name}");
  }
  std::set<std::string> names;
  for (size_t i = 0; i < node.size(); ++i) {
    YamlMap m(node[i], ctx.file, "class " + std::to_string(i));
    const int id = m.integer("id");
    const std::string name = m.string("name");
    if (id < 0) m.fail_key("id", "class IDs must not be negative");
    if (scene->classes.count(id))
      m.fail_key("id", "class ID " + std::to_string(id) + " given twice");
    if (!names.insert(name).second) m.fail_key("name", "class name '" + name + "' given twice");
    m.finish();
    scene->classes[id] = name;
  }
}

Lighting parse_lighting(const YAML::Node& node, ParseContext& ctx) {
  YamlMap m(node, ctx.file, "lighting");
  Lighting lighting;
  const YAML::Node ambient = m.required("ambient");
  lighting.ambient =
      ambient.IsSequence()
          ? Eigen::Vector3f(as_vector(ambient, 3, ctx.file, m.what("ambient")).cast<float>())
          : Eigen::Vector3f::Constant(
                static_cast<float>(as_number(ambient, ctx.file, m.what("ambient"))));
  const YAML::Node lights = m.optional("lights");
  if (lights.IsDefined()) {
    if (!lights.IsSequence()) fail_at(ctx.file, lights, "'lights' must be a list");
    for (size_t i = 0; i < lights.size(); ++i) {
      YamlMap lm(lights[i], ctx.file, "light " + std::to_string(i));
      Light light;
      const std::string type = lm.string("type");
      if (type == "directional") {
        light.type = Light::Type::kDirectional;
        const Eigen::Vector3d d = lm.vec3("direction");
        if (d.norm() < 1e-9) lm.fail_key("direction", "a light's direction must not be zero");
        light.direction = d.normalized();
      } else if (type == "point") {
        light.type = Light::Type::kPoint;
        light.position = lm.vec3("position");
        light.range = lm.number_in_or("range", 1e-3, 1e6, 3.0);
      } else {
        lm.fail_key("type", "unknown light type '" + type + "' (directional, point)");
      }
      light.intensity = lm.number_in("intensity", 0.0, 1e3);
      light.colour = lm.vec3_or("colour", Eigen::Vector3d::Ones()).cast<float>();
      lm.finish();
      lighting.lights.push_back(light);
    }
  }
  m.finish();
  return lighting;
}

// The room: a box of floor, four walls and a ceiling, floor at z = 0, centred on x = y = 0, each
// surface a quad facing inwards (shading is two-sided anyway).
void parse_room(const YAML::Node& node, ParseContext& ctx, Scene* scene) {
  YamlMap m(node, ctx.file, "room");
  const YAML::Node size_node = m.required("size");
  const Eigen::Vector3d size = as_vector(size_node, 3, ctx.file, m.what("size"));
  if ((size.array() <= 0.0).any())
    fail_at(ctx.file, size_node, m.what("size") + " must be positive");
  const Texture floor = parse_material(m.required("floor"), ctx, "floor of the room", 101);
  const Texture walls = parse_material(m.required("walls"), ctx, "walls of the room", 102);
  const Texture ceiling = parse_material(m.required("ceiling"), ctx, "ceiling of the room", 103);
  m.finish();
  const double hx = 0.5 * size.x(), hy = 0.5 * size.y(), h = size.z();
  auto add = [&](const Eigen::Vector2d& quad, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                 const Texture& tex) {
    SceneObject obj;
    obj.T_wo = SE3::from_rotation_translation(R, t);
    obj.shape = std::make_shared<Quad>(quad);
    obj.material = tex;
    scene->background.push_back(std::move(obj));
  };
  auto rot = [](const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
    Eigen::Matrix3d R;
    R.col(0) = x;
    R.col(1) = y;
    R.col(2) = x.cross(y);
    return R;
  };
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  add({size.x(), size.y()}, rot(X, Y), Eigen::Vector3d(0, 0, 0), floor);
  add({size.x(), size.y()}, rot(X, -Y), Eigen::Vector3d(0, 0, h), ceiling);
  // Walls: local x along the wall, local y up, normal (local z) into the room.
  add({size.y(), h}, rot(-Y, Z), Eigen::Vector3d(hx, 0, 0.5 * h), walls);
  add({size.y(), h}, rot(Y, Z), Eigen::Vector3d(-hx, 0, 0.5 * h), walls);
  add({size.x(), h}, rot(X, Z), Eigen::Vector3d(0, hy, 0.5 * h), walls);
  add({size.x(), h}, rot(-X, Z), Eigen::Vector3d(0, -hy, 0.5 * h), walls);
}

// Shared by objects (with id and class) and furniture (background, without).
void parse_item(const YAML::Node& node, ParseContext& ctx, bool is_object, size_t index,
                Scene* scene) {
  YamlMap m(node, ctx.file, (is_object ? "object " : "furniture ") + std::to_string(index));
  SceneObject obj;
  std::string context = m.context();
  if (is_object) {
    const YAML::Node id_node = m.required("id");
    const int id = as_int(id_node, ctx.file, m.what("id"));
    if (id < 1 || id > 65535)
      fail_at(ctx.file, id_node, "object IDs run from 1 to 65535 (uint16 instance images)");
    for (const auto& other : scene->objects) {
      if (other.id == static_cast<uint32_t>(id))
        fail_at(ctx.file, id_node, "object ID " + std::to_string(id) + " used twice");
    }
    obj.id = static_cast<uint32_t>(id);
    context = "object " + std::to_string(id);
    const YAML::Node cls = m.required("class");
    obj.class_name = as_string(cls, ctx.file, "'class' of " + context);
    bool found = false;
    for (const auto& [cid, name] : scene->classes) {
      if (name == obj.class_name) {
        obj.class_id = cid;
        found = true;
      }
    }
    if (!found)
      fail_at(ctx.file, cls,
              "class '" + obj.class_name + "' of " + context + " is not in 'classes'");
  } else {
    m.string_or("name", "");  // a label for the reader of the file
  }
  const uint32_t seed =
      static_cast<uint32_t>(obj.id * 1009u + index * 17u + (is_object ? 0u : 50000u));
  obj.T_wo = parse_pose(m.required("pose"), ctx, "pose of " + context);
  const YAML::Node scale = m.optional("scale");
  if (scale.IsDefined()) {
    obj.scale = as_number(scale, ctx.file, "'scale' of " + context);
    if (!(obj.scale > 0.0)) fail_at(ctx.file, scale, "'scale' of " + context + " must be positive");
  }
  obj.material = parse_material(m.required("material"), ctx, "material of " + context, seed);
  ParsedShape shape = parse_shape(m.required("shape"), ctx, "shape of " + context, seed);
  obj.shape = shape.shape;
  for (const auto& pm : shape.part_materials) obj.part_materials.push_back(pm ? *pm : obj.material);
  m.finish();
  (is_object ? scene->objects : scene->background).push_back(std::move(obj));
}

std::vector<TrajectoryPose> parse_trajectory(const YAML::Node& node, ParseContext& ctx, int frames,
                                             double fps, uint64_t seed) {
  YamlMap m(node, ctx.file, "trajectory");
  const std::string type = m.string("type");
  std::vector<TrajectoryPose> poses;
  if (type == "orbit") {
    OrbitParams p;
    p.target = m.vec3("target");
    p.radius = m.number_in("radius", 1e-3, 1e3);
    p.height = m.number("height");
    p.height_amplitude = m.number_or("height_amplitude", 0.0);
    p.start_deg = m.number_or("start_deg", 0.0);
    p.arc_deg = m.number_or("arc_deg", 360.0);
    poses = make_orbit(p, frames, fps);
  } else if (type == "walk") {
    WalkParams p;
    const YAML::Node wp = m.required("waypoints");
    for (const auto& v : as_points(wp, 3, 2, ctx.file, m.what("waypoints")))
      p.waypoints.emplace_back(v);
    const YAML::Node la = m.required("look_at");
    for (const auto& v : as_points(la, 3, 2, ctx.file, m.what("look_at")))
      p.look_at.emplace_back(v);
    if (p.look_at.size() != p.waypoints.size()) {
      fail_at(
          ctx.file, la,
          "'look_at' needs one point per waypoint (" + std::to_string(p.waypoints.size()) + ")");
    }
    p.jitter_position = m.number_in_or("jitter_position", 0.0, 1.0, 0.0);
    p.jitter_rotation_deg = m.number_in_or("jitter_rotation_deg", 0.0, 45.0, 0.0);
    p.seed = seed;
    poses = make_walk(p, frames, fps);
  } else if (type == "tum") {
    const YAML::Node file_node = m.required("file");
    const std::string path = resolve_path(ctx, as_string(file_node, ctx.file, m.what("file")));
    std::string err;
    const std::optional<Trajectory> tum = read_tum_trajectory(path, &err);
    if (!tum) fail_at(ctx.file, file_node, "cannot read the trajectory: " + err);
    for (const auto& [timestamp, T_wc] : *tum) poses.push_back({timestamp, T_wc});
    if (static_cast<int>(poses.size()) < frames) {
      fail_at(ctx.file, file_node,
              "the trajectory '" + path + "' has " + std::to_string(poses.size()) +
                  " poses, fewer than the scene's " + std::to_string(frames) + " frames");
    }
    poses.resize(static_cast<size_t>(frames));
  } else {
    m.fail_key("type", "unknown trajectory type '" + type + "' (orbit, walk, tum)");
  }
  m.finish();
  return poses;
}

// [[cup, bowl, vase], [laptop, book]]: class names of `classes`, two or more per group, each
// class in one group at most. Returns class IDs.
std::vector<std::vector<int>> parse_confusion_groups(const YAML::Node& node, ParseContext& ctx,
                                                     const std::map<int, std::string>& classes) {
  const std::string what = "'confusion_groups' of noise/detections";
  if (!node.IsSequence()) fail_at(ctx.file, node, what + " must be a list of lists of class names");
  std::map<std::string, int> id_of;
  for (const auto& [id, name] : classes) id_of[name] = id;
  std::map<int, size_t> group_of;
  std::vector<std::vector<int>> groups;
  for (size_t g = 0; g < node.size(); ++g) {
    const YAML::Node group = node[g];
    const std::string gwhat = "confusion group " + std::to_string(g + 1);
    if (!group.IsSequence() || group.size() < 2) {
      fail_at(ctx.file, group, gwhat + " must be a list of two or more class names");
    }
    std::vector<int> ids;
    for (size_t k = 0; k < group.size(); ++k) {
      const std::string name = as_string(group[k], ctx.file, "a class of " + gwhat);
      const auto it = id_of.find(name);
      if (it == id_of.end()) {
        fail_at(ctx.file, group[k], "class '" + name + "' of " + gwhat + " is not in 'classes'");
      }
      const auto [prev, fresh] = group_of.emplace(it->second, g);
      if (!fresh) {
        fail_at(ctx.file, group[k],
                "class '" + name + "' is in confusion group " + std::to_string(prev->second + 1) +
                    (prev->second == g ? " twice" : " already (a class belongs to one group)"));
      }
      ids.push_back(it->second);
    }
    groups.push_back(std::move(ids));
  }
  return groups;
}

NoiseParams parse_noise(const YAML::Node& node, ParseContext& ctx,
                        const std::map<int, std::string>& classes) {
  YamlMap m(node, ctx.file, "noise");
  NoiseParams n;
  n.enabled = m.boolean_or("enabled", true);
  SensorNoiseParams& s = n.sensor;
  s.depth_sigma = m.number_in_or("depth_sigma", 0.0, 1.0, s.depth_sigma);
  s.max_depth = m.number_in_or("max_depth", 0.0, 1e6, s.max_depth);
  s.edge_jump = m.number_in_or("edge_jump", 0.0, 100.0, s.edge_jump);
  s.edge_jump_relative = m.number_in_or("edge_jump_relative", 0.0, 10.0, s.edge_jump_relative);
  s.edge_hole_probability =
      m.number_in_or("edge_hole_probability", 0.0, 1.0, s.edge_hole_probability);
  s.rgb_sigma = m.number_in_or("rgb_sigma", 0.0, 255.0, s.rgb_sigma);
  const YAML::Node det = m.optional("detections");
  if (det.IsDefined()) {
    YamlMap d(det, ctx.file, "noise/detections");
    DetectionNoiseParams& p = n.detection;
    // The profile first: it sets the rates, the keys given beside it override them.
    const YAML::Node profile_node = d.optional("profile");
    if (profile_node.IsDefined()) {
      const std::string name = as_string(profile_node, ctx.file, d.what("profile"));
      const auto profile = detector_profile_from_name(name);
      if (!profile) {
        fail_at(ctx.file, profile_node,
                "unknown detector profile '" + name + "' (" + kDetectorProfileNames + ")");
      }
      set_detector_profile(*profile, &p);
    }
    p.box_jitter_px = d.number_in_or("box_jitter_px", 0.0, 1e3, p.box_jitter_px);
    p.miss_rate = d.number_in_or("miss_rate", 0.0, 1.0, p.miss_rate);
    p.false_positive_rate = d.number_in_or("false_positive_rate", 0.0, 1.0, p.false_positive_rate);
    p.confusion_rate = d.number_in_or("confusion_rate", 0.0, 1.0, p.confusion_rate);
    p.confusion_within_groups =
        d.boolean_or("confusion_within_groups", p.confusion_within_groups);
    const YAML::Node groups = d.optional("confusion_groups");
    if (groups.IsDefined()) p.confusion_groups = parse_confusion_groups(groups, ctx, classes);
    p.false_positive_recurring =
        d.number_in_or("false_positive_recurring", 0.0, 1.0, p.false_positive_recurring);
    p.clutter_spots = d.integer_or("clutter_spots", p.clutter_spots);
    if (p.clutter_spots < 0 || p.clutter_spots > 1000)
      d.fail_key("clutter_spots", d.what("clutter_spots") + " must be in [0, 1000]");
    p.min_visible_fraction =
        d.number_in_or("min_visible_fraction", 0.0, 1.0, p.min_visible_fraction);
    p.min_box_px = d.number_in_or("min_box_px", 0.0, 1e4, p.min_box_px);
    d.finish();
  }
  m.finish();
  return n;
}

Scene parse_root(const YAML::Node& root, ParseContext& ctx, const std::string& default_name,
                 const SceneOverrides& overrides) {
  YamlMap m(root, ctx.file, "the scene");
  Scene scene;
  scene.source = ctx.file;
  scene.name = m.string_or("name", default_name);
  const YAML::Node seed = m.required("seed");
  const int seed_value = as_int(seed, ctx.file, "'seed'");
  if (seed_value < 0) fail_at(ctx.file, seed, "'seed' must not be negative");
  scene.seed = static_cast<uint64_t>(seed_value);
  const int frames = static_cast<int>(m.number_in("frames", 1, 1e6));
  const double fps = m.number_in_or("fps", 1e-3, 1e4, 30.0);
  scene.camera = parse_camera(m.required("camera"), ctx, &scene);
  parse_classes(m.required("classes"), ctx, &scene);
  scene.lighting = parse_lighting(m.required("lighting"), ctx);
  scene.background_colour = m.vec3_or("background_colour", Eigen::Vector3d::Zero()).cast<float>();
  const YAML::Node room = m.optional("room");
  if (room.IsDefined()) parse_room(room, ctx, &scene);
  const YAML::Node furniture = m.optional("furniture");
  if (furniture.IsDefined()) {
    if (!furniture.IsSequence()) fail_at(ctx.file, furniture, "'furniture' must be a list");
    for (size_t i = 0; i < furniture.size(); ++i) parse_item(furniture[i], ctx, false, i, &scene);
  }
  const YAML::Node objects = m.required("objects");
  if (!objects.IsSequence()) fail_at(ctx.file, objects, "'objects' must be a list");
  for (size_t i = 0; i < objects.size(); ++i) parse_item(objects[i], ctx, true, i, &scene);
  scene.trajectory = parse_trajectory(m.required("trajectory"), ctx, frames, fps, scene.seed);
  const YAML::Node noise = m.optional("noise");
  if (noise.IsDefined()) scene.noise = parse_noise(noise, ctx, scene.classes);
  m.finish();
  // The command line's profile replaces the file's and its rates (thresholds and groups stay).
  if (overrides.detector_profile) {
    set_detector_profile(*overrides.detector_profile, &scene.noise.detection);
  }
  return scene;
}

}  // namespace
}  // namespace detail

std::optional<Scene> parse_scene(const std::string& yaml_text, const std::string& name_for_messages,
                                 const std::string& base_dir, const MeshLoader& loader,
                                 std::string* error, const SceneOverrides& overrides) {
  detail::ParseContext ctx;
  ctx.file = name_for_messages;
  ctx.base_dir = base_dir;
  ctx.loader = &loader;
  try {
    const YAML::Node root = YAML::Load(yaml_text);
    Scene scene =
        detail::parse_root(root, ctx, std::filesystem::path(name_for_messages).stem().string(),
                           overrides);
    const std::string problem = validate_scene(scene);
    if (!problem.empty()) throw detail::SceneError(name_for_messages + ": " + problem);
    return scene;
  } catch (const detail::SceneError& e) {
    if (error) *error = e.what();
  } catch (const YAML::Exception& e) {
    if (error) *error = detail::location(name_for_messages, e.mark) + ": " + e.msg;
  }
  return std::nullopt;
}

std::optional<Scene> load_scene(const std::string& yaml_path, const MeshLoader& loader,
                                std::string* error, const SceneOverrides& overrides) {
  std::ifstream in(yaml_path);
  if (!in) {
    if (error) *error = yaml_path + ": cannot open the scene file";
    return std::nullopt;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string base_dir = std::filesystem::path(yaml_path).parent_path().string();
  return parse_scene(ss.str(), yaml_path, base_dir, loader, error, overrides);
}

}  // namespace dqo::sim
