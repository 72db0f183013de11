#include "ros_params.h"

#include <cstdlib>
#include <charconv>
#include <cstdio>
#include <sstream>
#include <vector>

#include <ros/param.h>

namespace dqo::ros_bridge {
namespace {

void quote(std::ostream& out, const std::string& s) {
  out << '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out << '\\' << c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out << buf;
    } else {
      out << c;
    }
  }
  out << '"';
}

void write(std::ostream& out, XmlRpc::XmlRpcValue& v) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      out << (static_cast<bool>(v) ? "true" : "false");
      break;
    case XmlRpc::XmlRpcValue::TypeInt:
      out << static_cast<int>(v);
      break;
    case XmlRpc::XmlRpcValue::TypeDouble: {
      char buf[40];
      const auto r = std::to_chars(buf, buf + sizeof(buf), static_cast<double>(v));
      std::string text(buf, r.ptr);
      if (text.find_first_of(".en") == std::string::npos) text += ".0";  // stays a real number
      out << text;
      break;
    }
    case XmlRpc::XmlRpcValue::TypeString:
      quote(out, static_cast<std::string>(v));
      break;
    case XmlRpc::XmlRpcValue::TypeArray:
      out << '[';
      for (int i = 0; i < v.size(); ++i) {
        if (i) out << ", ";
        write(out, v[i]);
      }
      out << ']';
      break;
    case XmlRpc::XmlRpcValue::TypeStruct: {
      out << '{';
      bool first = true;
      for (auto& kv : v) {
        if (!first) out << ", ";
        first = false;
        quote(out, kv.first);
        out << ": ";
        write(out, kv.second);
      }
      out << '}';
      break;
    }
    default:  // dates, binary, invalid: nothing a parameter file holds; the loader names the key
      out << "\"<unsupported parameter type>\"";
      break;
  }
}

}  // namespace

std::string to_yaml(const XmlRpc::XmlRpcValue& value) {
  XmlRpc::XmlRpcValue copy = value;  // XmlRpcValue's accessors are not const
  std::ostringstream out;
  write(out, copy);
  return out.str();
}

std::optional<tracking::TrackingConfig> read_tracking_config(const ros::NodeHandle& private_nh,
                                                             std::string* error) {
  std::string text = "{";
  for (const char* section : {"tracker", "mapping_keyframes", "stream"}) {
    XmlRpc::XmlRpcValue value;
    if (!private_nh.getParam(section, value)) continue;
    if (text.size() > 1) text += ", ";
    text += std::string("\"") + section + "\": " + to_yaml(value);
  }
  text += "}";
  return tracking::parse_tracking_config(text, "ROS parameters of " + private_nh.getNamespace(), error,
                                         {}, /*positions=*/false);
}

std::string default_output_dir() {
  const char* ros_home = std::getenv("ROS_HOME");
  const char* home = std::getenv("HOME");
  return ros_home ? std::string(ros_home) + "/dqo_map" : std::string(home ? home : ".") + "/.ros/dqo_map";
}

std::set<std::string> unknown_private_params(const ros::NodeHandle& private_nh,
                                             const std::set<std::string>& known) {
  std::set<std::string> unknown;
  std::vector<std::string> names;
  if (!ros::param::getParamNames(names)) return unknown;
  const std::string prefix = private_nh.getNamespace() + "/";
  for (const std::string& name : names) {
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rel = name.substr(prefix.size());
    const std::string head = rel.substr(0, rel.find('/'));
    if (!known.count(head)) unknown.insert(rel);
  }
  return unknown;
}

}  // namespace dqo::ros_bridge
