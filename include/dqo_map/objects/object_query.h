#pragma once
// list_objects' answer, apart from ROS: the objects of one class, matched as a user types a class
// name (case-insensitively), and a message that says what was found, or, for a class no object
// has, which classes the map does hold, so that a typo or a class not yet seen is not met with
// silence.
#include <string>
#include <vector>

#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

struct ClassQueryResult {
  std::vector<MapObject> objects;  // in the order given
  std::string message;
};

// `class_name` empty: every object.
ClassQueryResult objects_of_class(const std::vector<MapObject>& objects, const std::string& class_name);

}  // namespace dqo::objects
