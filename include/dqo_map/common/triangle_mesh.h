#pragma once
// An indexed triangle mesh: what sim/ builds procedurally and io/ loads from PLY/OBJ.

#include <array>
#include <vector>

#include <Eigen/Core>

namespace dqo {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;  // counter-clockwise seen from outside
  std::vector<Eigen::Vector3d> colours;       // per vertex in [0, 1]; empty when none

  bool empty() const { return triangles.empty(); }
};

}  // namespace dqo
