#pragma once
// The object stage's state file (DESIGN.md: IDs never reused, also across restarts): the next ID
// and the objects (ellipsoid, class votes, counts; not their observations, whose keyframes belong
// to one tracker run). Text, one object per line plus its class name, numbers in the shortest text
// that reads back to the same double. Written to a temporary sibling and renamed, so a crash
// leaves either the old file or the new one.
//
//   dqo_object_state 1
//   next_id N
//   map MAP_ID (rest of the line: the map the objects' poses refer to; absent in older files = "")
//   object ID STATE CLASS HAS_QUADRIC FROM_BOXES cx cy cz qx qy qz qw a1 a2 a3 COUNT MISSED
//          FIRST_KF LAST_KF NVOTES [CLASS VOTES]...
//   name CLASS_NAME (rest of the line; may be empty)
//   box cx cy cz qx qy qz qw hx hy hz (only for objects with a fitted box)
#include <map>
#include <string>
#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

bool write_state_file(const std::string& path, const std::map<ObjectId, MapObject>& objects,
                      ObjectId next_id, const std::string& map_id, std::string* error);
// On failure nothing is returned through the pointers and *error says "path:LINE: why".
bool read_state_file(const std::string& path, std::map<ObjectId, MapObject>* objects,
                     ObjectId* next_id, std::string* map_id, std::string* error);

}  // namespace dqo::objects
