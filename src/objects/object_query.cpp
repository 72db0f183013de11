#include "dqo_map/objects/object_query.h"

#include <algorithm>
#include <cctype>
#include <set>

namespace dqo::objects {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

ClassQueryResult objects_of_class(const std::vector<MapObject>& objects, const std::string& class_name) {
  ClassQueryResult out;
  const std::string wanted = lower(class_name);
  std::set<std::string> classes;
  for (const MapObject& o : objects) {
    classes.insert(o.class_name);
    if (wanted.empty() || lower(o.class_name) == wanted) out.objects.push_back(o);
  }
  const std::string n = std::to_string(out.objects.size());
  if (wanted.empty()) {
    out.message = n + (out.objects.size() == 1 ? " object" : " objects");
  } else if (!out.objects.empty()) {
    out.message = n + " of class '" + out.objects.front().class_name + "'";
  } else if (classes.empty()) {
    out.message = "no object of class '" + class_name + "': the map holds no objects yet";
  } else {
    std::string known;
    for (const std::string& c : classes) known += (known.empty() ? "" : ", ") + c;
    out.message = "no object of class '" + class_name + "'; the map's classes: " + known;
  }
  return out;
}

}  // namespace dqo::objects
