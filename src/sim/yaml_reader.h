#pragma once
// Strict reading of YAML maps for the scene loader (private to sim/): every key must be read
// exactly once or it is reported as unknown; every error carries "FILE:LINE:COLUMN: ".
// yaml-cpp stays out of the public headers.

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace dqo::sim::detail {

// Thrown while loading; load_scene() turns it into its error string. Never crosses the library's
// boundary.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// "FILE:LINE:COLUMN" (1-based) of a node; "FILE" alone when the node has no position.
std::string location(const std::string& file, const YAML::Mark& mark);

[[noreturn]] void fail_at(const std::string& file, const YAML::Node& node,
                          const std::string& message);

// Scalars and short sequences, with messages that say what was expected. `what` names the value
// ("'radius' of object 3").
double as_number(const YAML::Node& node, const std::string& file, const std::string& what);
int as_int(const YAML::Node& node, const std::string& file, const std::string& what);
bool as_bool(const YAML::Node& node, const std::string& file, const std::string& what);
std::string as_string(const YAML::Node& node, const std::string& file, const std::string& what);
// A sequence of exactly n numbers.
Eigen::VectorXd as_vector(const YAML::Node& node, size_t n, const std::string& file,
                          const std::string& what);
// A sequence of points of dimension n each (at least min_count of them).
std::vector<Eigen::VectorXd> as_points(const YAML::Node& node, size_t n, size_t min_count,
                                       const std::string& file, const std::string& what);

class YamlMap {
 public:
  // `context` names the map in messages ("camera", "object 3", "shape of object 3").
  YamlMap(const YAML::Node& node, std::string file, std::string context);

  bool has(const std::string& key) const;
  // The value of a key that must be there; marks it read.
  YAML::Node required(const std::string& key);
  // The value, or an undefined node when absent; marks it read.
  YAML::Node optional(const std::string& key);

  double number(const std::string& key);
  double number_or(const std::string& key, double fallback);
  // Both range checks are inclusive; the message names the key and the range.
  double number_in(const std::string& key, double lo, double hi);
  double number_in_or(const std::string& key, double lo, double hi, double fallback);
  int integer(const std::string& key);
  int integer_or(const std::string& key, int fallback);
  bool boolean_or(const std::string& key, bool fallback);
  std::string string(const std::string& key);
  std::string string_or(const std::string& key, const std::string& fallback);
  Eigen::Vector2d vec2(const std::string& key);
  Eigen::Vector3d vec3(const std::string& key);
  Eigen::Vector3d vec3_or(const std::string& key, const Eigen::Vector3d& fallback);

  // Reports the first key that was never read (unknown or not allowed here) with its position
  // and the keys that are. Call once everything expected has been read.
  void finish() const;

  [[noreturn]] void fail(const std::string& message) const;  // at the map itself
  [[noreturn]] void fail_key(const std::string& key, const std::string& message) const;

  const YAML::Node& node() const { return node_; }
  const std::string& file() const { return file_; }
  const std::string& context() const { return context_; }
  std::string what(const std::string& key) const { return "'" + key + "' of " + context_; }

 private:
  YAML::Node node_;
  std::string file_;
  std::string context_;
  std::set<std::string> read_;
  std::vector<std::string> allowed_;  // every key asked for, for the message of finish()
};

}  // namespace dqo::sim::detail
