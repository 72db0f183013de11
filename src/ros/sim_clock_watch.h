#pragma once
// Whether a played bag has stopped: under sim time a bag's /clock stands still when it ends or is
// paused, so a check that finds ROS time where the previous check left it sees a stopped clock. The
// nodes that warn about missing input (tracking, association) say so instead of a WARN a minute.
// Call stopped() once per periodic check.
#include <ros/time.h>

namespace dqo::ros_bridge {

class SimClockWatch {
 public:
  bool stopped() {
    const ros::Time now = ros::Time::now();
    const bool same = ros::Time::isSimTime() && now == last_;
    last_ = now;
    return same;
  }

 private:
  ros::Time last_;
};

}  // namespace dqo::ros_bridge
