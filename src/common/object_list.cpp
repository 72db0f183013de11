#include "dqo_map/common/object_list.h"

#include <cmath>
#include <limits>
#include <set>

#include "dqo_map/common/text_util.h"

namespace dqo {

namespace {

constexpr size_t kFields = 12;
constexpr char kColumns[] = "id class tx ty tz qx qy qz qw a1 a2 a3";
// A quaternion this close to unit length is kept as written, so that exact round trips stay exact.
constexpr double kUnitTolerance = 1e-12;
constexpr double kMinQuaternionNorm = 1e-6;

// Why the entry cannot be written or was not read; empty when it is sound.
std::string entry_problem(const ObjectListEntry& e) {
  if (!e.centre.allFinite()) return "centre is not finite";
  if (!e.rotation.coeffs().allFinite()) return "quaternion is not finite";
  if (!e.semi_axes.allFinite()) return "axes are not finite";
  if (!(e.rotation.norm() >= kMinQuaternionNorm)) return "quaternion has (near) zero norm";
  if ((e.semi_axes.array() < 0.0).any()) return "negative axis";
  return {};
}

}  // namespace

std::optional<std::vector<ObjectListEntry>> read_object_list(const std::string& path,
                                                             std::string* error) {
  std::vector<text::TextLine> lines;
  if (!text::read_text_lines(path, &lines, error)) return std::nullopt;
  std::vector<ObjectListEntry> objects;
  std::set<uint64_t> ids;
  for (const text::TextLine& line : lines) {
    const auto bad = [&](const std::string& why) {
      text::fail(error, text::located(path, line.number, why));
      return std::nullopt;
    };
    if (line.tokens.size() != kFields) {
      return bad("expected " + std::to_string(kFields) + " fields `" + kColumns + "`, found " +
                 std::to_string(line.tokens.size()));
    }
    long long id = 0, class_id = 0;
    if (!text::parse_int(line.tokens[0], &id) || id < 1) {
      return bad("id '" + line.tokens[0] + "' is not a positive integer");
    }
    if (!text::parse_int(line.tokens[1], &class_id) || class_id < std::numeric_limits<int>::min() ||
        class_id > std::numeric_limits<int>::max()) {
      return bad("class '" + line.tokens[1] + "' is not an integer in range");
    }
    static const char* kNames[10] = {"tx", "ty", "tz", "qx", "qy", "qz", "qw", "a1", "a2", "a3"};
    double v[10];
    for (int k = 0; k < 10; ++k) {
      if (!text::parse_double(line.tokens[2 + k], &v[k])) {
        return bad(std::string(kNames[k]) + " '" + line.tokens[2 + k] + "' is not a finite number");
      }
    }
    ObjectListEntry e;
    e.id = static_cast<uint64_t>(id);
    e.class_id = static_cast<int>(class_id);
    e.centre = Eigen::Vector3d(v[0], v[1], v[2]);
    e.rotation = Eigen::Quaterniond(v[6], v[3], v[4], v[5]);
    e.semi_axes = Eigen::Vector3d(v[7], v[8], v[9]);
    const std::string problem = entry_problem(e);
    if (!problem.empty()) return bad(problem);
    if (std::abs(e.rotation.norm() - 1.0) > kUnitTolerance) e.rotation.normalize();
    if (!ids.insert(e.id).second) return bad("object " + std::to_string(e.id) + " listed twice");
    objects.push_back(e);
  }
  return objects;
}

bool write_object_list(const std::string& path, const std::vector<ObjectListEntry>& objects,
                       std::string* error) {
  std::string content = std::string("# ") + kColumns +
                        "  (centre, unit quaternion scalar last, semi-axes or half extents)\n";
  std::set<uint64_t> ids;
  for (const ObjectListEntry& e : objects) {
    const std::string problem = entry_problem(e);
    if (!problem.empty()) {
      return text::fail(error, path + ": object " + std::to_string(e.id) + ": " + problem);
    }
    if (e.id == 0 || e.id > static_cast<uint64_t>(std::numeric_limits<long long>::max())) {
      return text::fail(
          error, path + ": object ID " + std::to_string(e.id) + " out of range (1 to 2^63 - 1)");
    }
    if (!ids.insert(e.id).second) {
      return text::fail(error, path + ": object " + std::to_string(e.id) + " listed twice");
    }
    const Eigen::Vector3d& c = e.centre;
    const Eigen::Quaterniond& q = e.rotation;
    const Eigen::Vector3d& a = e.semi_axes;
    for (const std::string& field :
         {std::to_string(e.id), std::to_string(e.class_id), text::format_double(c.x()),
          text::format_double(c.y()), text::format_double(c.z()), text::format_double(q.x()),
          text::format_double(q.y()), text::format_double(q.z()), text::format_double(q.w()),
          text::format_double(a.x()), text::format_double(a.y()), text::format_double(a.z())}) {
      if (content.back() != '\n') content += ' ';
      content += field;
    }
    content += '\n';
  }
  return text::write_file_atomically(path, content, error);
}

OrientedBox to_oriented_box(const ObjectListEntry& entry) {
  OrientedBox box;
  box.centre = entry.centre;
  box.rotation = entry.rotation.normalized().toRotationMatrix();
  box.half_extents = entry.semi_axes;
  return box;
}

ObjectListEntry make_object_list_entry(uint64_t id, int class_id, const OrientedBox& box) {
  ObjectListEntry e;
  e.id = id;
  e.class_id = class_id;
  e.centre = box.centre;
  e.rotation = Eigen::Quaterniond(box.rotation).normalized();
  e.semi_axes = box.half_extents;
  return e;
}

}  // namespace dqo
