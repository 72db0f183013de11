#include "yaml_reader.h"

#include <cmath>
#include <map>
#include <sstream>
#include <utility>

namespace dqo::sim::detail {

std::string location(const std::string& file, const YAML::Mark& mark) {
  if (mark.is_null()) return file;
  return file + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

void fail_at(const std::string& file, const YAML::Node& node, const std::string& message) {
  throw SceneError(location(file, node.Mark()) + ": " + message);
}

double as_number(const YAML::Node& node, const std::string& file, const std::string& what) {
  if (!node.IsScalar()) fail_at(file, node, what + " must be a number");
  double v;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    fail_at(file, node, what + " must be a number, not '" + node.Scalar() + "'");
  }
  if (!std::isfinite(v)) fail_at(file, node, what + " must be finite");
  return v;
}

int as_int(const YAML::Node& node, const std::string& file, const std::string& what) {
  if (!node.IsScalar()) fail_at(file, node, what + " must be an integer");
  try {
    return node.as<int>();
  } catch (const YAML::Exception&) {
    fail_at(file, node, what + " must be an integer, not '" + node.Scalar() + "'");
  }
}

bool as_bool(const YAML::Node& node, const std::string& file, const std::string& what) {
  if (!node.IsScalar()) fail_at(file, node, what + " must be true or false");
  try {
    return node.as<bool>();
  } catch (const YAML::Exception&) {
    fail_at(file, node, what + " must be true or false, not '" + node.Scalar() + "'");
  }
}

std::string as_string(const YAML::Node& node, const std::string& file, const std::string& what) {
  if (!node.IsScalar()) fail_at(file, node, what + " must be a string");
  return node.Scalar();
}

Eigen::VectorXd as_vector(const YAML::Node& node, size_t n, const std::string& file,
                          const std::string& what) {
  if (!node.IsSequence() || node.size() != n) {
    fail_at(file, node, what + " must be a list of " + std::to_string(n) + " numbers");
  }
  Eigen::VectorXd v(static_cast<Eigen::Index>(n));
  for (size_t i = 0; i < n; ++i) v[static_cast<Eigen::Index>(i)] = as_number(node[i], file, what);
  return v;
}

std::vector<Eigen::VectorXd> as_points(const YAML::Node& node, size_t n, size_t min_count,
                                       const std::string& file, const std::string& what) {
  if (!node.IsSequence() || node.size() < min_count) {
    fail_at(file, node,
            what + " must be a list of at least " + std::to_string(min_count) + " points [" +
                std::to_string(n) + " numbers each]");
  }
  std::vector<Eigen::VectorXd> pts;
  for (size_t i = 0; i < node.size(); ++i) pts.push_back(as_vector(node[i], n, file, what));
  return pts;
}

YamlMap::YamlMap(const YAML::Node& node, std::string file, std::string context)
    : node_(node), file_(std::move(file)), context_(std::move(context)) {
  if (!node_.IsMap()) fail_at(file_, node_, context_ + " must be a map of keys to values");
}

bool YamlMap::has(const std::string& key) const {
  const YAML::Node& n = node_;
  return n[key].IsDefined();
}

YAML::Node YamlMap::required(const std::string& key) {
  allowed_.push_back(key);
  const YAML::Node& n = node_;
  YAML::Node v = n[key];
  if (!v.IsDefined() || v.IsNull()) fail("missing field '" + key + "' in " + context_);
  read_.insert(key);
  return v;
}

YAML::Node YamlMap::optional(const std::string& key) {
  allowed_.push_back(key);
  const YAML::Node& n = node_;
  YAML::Node v = n[key];
  if (v.IsDefined()) read_.insert(key);
  return v;
}

double YamlMap::number(const std::string& key) {
  return as_number(required(key), file_, what(key));
}

double YamlMap::number_or(const std::string& key, double fallback) {
  const YAML::Node v = optional(key);
  return v.IsDefined() ? as_number(v, file_, what(key)) : fallback;
}

double YamlMap::number_in(const std::string& key, double lo, double hi) {
  const YAML::Node v = required(key);
  const double x = as_number(v, file_, what(key));
  if (x < lo || x > hi) {
    std::ostringstream ss;
    ss << what(key) << " must lie in [" << lo << ", " << hi << "], not " << x;
    fail_at(file_, v, ss.str());
  }
  return x;
}

double YamlMap::number_in_or(const std::string& key, double lo, double hi, double fallback) {
  return has(key) ? number_in(key, lo, hi) : (optional(key), fallback);
}

int YamlMap::integer(const std::string& key) { return as_int(required(key), file_, what(key)); }

int YamlMap::integer_or(const std::string& key, int fallback) {
  const YAML::Node v = optional(key);
  return v.IsDefined() ? as_int(v, file_, what(key)) : fallback;
}

bool YamlMap::boolean_or(const std::string& key, bool fallback) {
  const YAML::Node v = optional(key);
  return v.IsDefined() ? as_bool(v, file_, what(key)) : fallback;
}

std::string YamlMap::string(const std::string& key) {
  return as_string(required(key), file_, what(key));
}

std::string YamlMap::string_or(const std::string& key, const std::string& fallback) {
  const YAML::Node v = optional(key);
  return v.IsDefined() ? as_string(v, file_, what(key)) : fallback;
}

Eigen::Vector2d YamlMap::vec2(const std::string& key) {
  return as_vector(required(key), 2, file_, what(key));
}

Eigen::Vector3d YamlMap::vec3(const std::string& key) {
  return as_vector(required(key), 3, file_, what(key));
}

Eigen::Vector3d YamlMap::vec3_or(const std::string& key, const Eigen::Vector3d& fallback) {
  const YAML::Node v = optional(key);
  return v.IsDefined() ? Eigen::Vector3d(as_vector(v, 3, file_, what(key))) : fallback;
}

void YamlMap::finish() const {
  std::map<std::string, int> seen;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = it->first.IsScalar() ? it->first.Scalar() : std::string("?");
    if (++seen[key] > 1) fail_at(file_, it->first, "key '" + key + "' given twice in " + context_);
    if (read_.count(key)) continue;
    std::set<std::string> allowed(allowed_.begin(), allowed_.end());
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    fail_at(file_, it->first,
            "unknown key '" + key + "' in " + context_ +
                (list.empty() ? "" : " (allowed here: " + list + ")"));
  }
}

void YamlMap::fail(const std::string& message) const { fail_at(file_, node_, message); }

void YamlMap::fail_key(const std::string& key, const std::string& message) const {
  const YAML::Node& n = node_;
  const YAML::Node v = n[key];
  fail_at(file_, v.IsDefined() ? v : node_, message);
}

}  // namespace dqo::sim::detail
