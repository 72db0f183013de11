#pragma once
// Poses from messages for the rostests that compare them with ground truth (they link dqo_common;
// ros_test_util.h stays free of the core's headers for the tests that do not). Written here rather
// than taken from the nodes' conversions so that a test checks the nodes against an independent
// reading.
#include <algorithm>
#include <cmath>

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>

#include "dqo_map/geometry/se3.h"

namespace dqo::ros_test {

inline SE3 to_se3(const geometry_msgs::Pose& p) {
  return SE3(Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z),
             Eigen::Vector3d(p.position.x, p.position.y, p.position.z));
}
inline SE3 to_se3(const geometry_msgs::Transform& t) {
  return SE3(Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z),
             Eigen::Vector3d(t.translation.x, t.translation.y, t.translation.z));
}
// The rotation angle of T, degrees.
inline double angle_deg(const SE3& T) {
  return 2.0 * std::acos(std::min(1.0, std::abs(T.quaternion().w()))) * 180.0 / M_PI;
}

}  // namespace dqo::ros_test
