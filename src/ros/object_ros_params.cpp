#include "object_ros_params.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include "dqo_map/objects/params_yaml.h"
#include "ros_params.h"

namespace dqo::ros_bridge {

std::optional<objects::ObjectMapperParams> read_object_params(const ros::NodeHandle& private_nh,
                                                              std::string* error) {
  std::string text = "{}";
  XmlRpc::XmlRpcValue value;
  if (private_nh.getParam("objects", value)) text = "{\"objects\": " + to_yaml(value) + "}";
  return objects::parse_object_params(text, "ROS parameters of " + private_nh.getNamespace(), error, {},
                                      /*positions=*/false);
}

namespace {

bool read_int(XmlRpc::XmlRpcValue& v, int min, int max, int* out) {
  if (v.getType() != XmlRpc::XmlRpcValue::TypeInt) return false;
  const int i = static_cast<int>(v);
  if (i < min || i > max) return false;
  *out = i;
  return true;
}

}  // namespace

bool read_mask_classes(const ros::NodeHandle& private_nh, MaskDetectionParams* params,
                       std::string* error) {
  XmlRpc::XmlRpcValue table;
  if (!private_nh.getParam("classes", table)) return true;  // no table: every instance gets the default
  const std::string where = private_nh.resolveName("classes");
  if (table.getType() != XmlRpc::XmlRpcValue::TypeArray) {
    *error = where + " must be a list of {value | colour, class_id, class_name}";
    return false;
  }
  for (int i = 0; i < table.size(); ++i) {
    XmlRpc::XmlRpcValue& e = table[i];
    const std::string entry = where + "[" + std::to_string(i) + "]";
    if (e.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
      *error = entry + " is not a map";
      return false;
    }
    for (auto& kv : e) {
      if (kv.first != "value" && kv.first != "colour" && kv.first != "class_id" && kv.first != "class_name") {
        *error = entry + ": unknown key '" + kv.first + "' (value, colour, class_id, class_name)";
        return false;
      }
    }
    if (e.hasMember("value") == e.hasMember("colour")) {
      *error = entry + " needs exactly one of value (mono masks) and colour [r, g, b] (colour masks)";
      return false;
    }
    uint32_t label = 0;
    if (e.hasMember("value")) {
      int v = 0;
      if (!read_int(e["value"], 1, 65535, &v)) {
        *error = entry + ".value must be an integer in [1, 65535] (0 means no instance)";
        return false;
      }
      label = static_cast<uint32_t>(v);
    } else {
      XmlRpc::XmlRpcValue& c = e["colour"];
      int rgb[3] = {0, 0, 0};
      bool ok = c.getType() == XmlRpc::XmlRpcValue::TypeArray && c.size() == 3;
      for (int k = 0; ok && k < 3; ++k) ok = read_int(c[k], 0, 255, &rgb[k]);
      if (!ok) {
        *error = entry + ".colour must be [r, g, b] with integers in [0, 255]";
        return false;
      }
      label = pack_rgb(rgb[0], rgb[1], rgb[2]);
      if (label == 0) {
        *error = entry + ".colour [0, 0, 0] is black, which means no instance";
        return false;
      }
    }
    MaskClass cls;
    if (!e.hasMember("class_id") || !read_int(e["class_id"], 0, 1 << 30, &cls.class_id)) {
      *error = entry + ".class_id must be a non-negative integer";
      return false;
    }
    if (!e.hasMember("class_name") || e["class_name"].getType() != XmlRpc::XmlRpcValue::TypeString) {
      *error = entry + ".class_name must be a string";
      return false;
    }
    cls.class_name = static_cast<std::string>(e["class_name"]);
    if (!params->classes.emplace(label, cls).second) {
      *error = entry + " gives a label that an earlier entry gave already";
      return false;
    }
  }
  return true;
}

}  // namespace dqo::ros_bridge
