#pragma once
// Object list files: one object per line, `id class tx ty tz qx qy qz qw a1 a2 a3`.
//
// The same text serves two files (DESIGN.md, Data on disk):
//   objects.txt     the map's objects as ellipsoids: centre, rotation (unit quaternion, scalar
//                   last; its columns are the ellipsoid's axes in world), semi-axes a1 a2 a3 (the
//                   format RO-MAP and VOOM write, for comparison with other object SLAM systems);
//   objects_gt.txt  ground-truth oriented boxes: the same numbers with half extents in place of
//                   semi-axes.
// For evaluation both mean the same thing: the box of the ellipsoid has half extents = semi-axes
// (METHOD.md §6), so an entry is a box either way (to_oriented_box).
//
// Lines whose first non-blank character is '#' and blank lines are skipped. Written with the
// shortest decimal text that parses back to the same double, so a write/read round trip is exact.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "dqo_map/geometry/oriented_box.h"

namespace dqo {

struct ObjectListEntry {
  // 1 to 2^63 - 1: 0 means "no object" throughout the package (instance images, mapper results).
  uint64_t id = 0;
  int class_id = 0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  // Unit quaternion. The reader normalises one that is not unit to 1e-12 and keeps one that is
  // bit for bit, so files written from unit quaternions read back exactly.
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d semi_axes = Eigen::Vector3d::Zero();  // >= 0 (half extents for boxes)
};

// Objects in file order. nullopt and *error ("path:LINE: why") when the file cannot be read or a
// line is malformed: not 12 fields, an ID or class that is not an integer in range (ID >= 1), a
// number that is not finite, a quaternion of (near) zero norm, a negative axis, an ID listed twice.
std::optional<std::vector<ObjectListEntry>> read_object_list(const std::string& path,
                                                             std::string* error = nullptr);

// Writes atomically (temporary sibling, then rename), with a header comment naming the columns.
// Fails (nothing written) for non-finite numbers, a zero quaternion, negative axes, ID 0 or
// duplicate IDs, so that what it writes always reads back.
bool write_object_list(const std::string& path, const std::vector<ObjectListEntry>& objects,
                       std::string* error = nullptr);

// The entry as a box in world: half extents = semi-axes, rotation from the (normalised) quaternion.
OrientedBox to_oriented_box(const ObjectListEntry& entry);

// The inverse of to_oriented_box, for writers; box.rotation must be a rotation.
ObjectListEntry make_object_list_entry(uint64_t id, int class_id, const OrientedBox& box);

}  // namespace dqo
