#include "dqo_map/config/yaml_schema.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

namespace dqo::config {
namespace {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

std::string join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// Shortest text that reads back to the same value (float or double).
template <typename V>
std::string shown(V v) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, r.ptr);
}

struct Reader {
  std::string source;
  bool positions = true;

  [[noreturn]] void fail(const YAML::Node& node, const std::string& message) const {
    std::string where = source;
    if (positions && node.Mark().line >= 0) {
      where += ":" + std::to_string(node.Mark().line + 1) + ":" +
               std::to_string(node.Mark().column + 1);
    }
    throw ConfigError(where + ": " + message);
  }

  double number(const YAML::Node& node, const std::string& path, const Field& f) const {
    if (!node.IsScalar()) fail(node, "'" + path + "' must be a number");
    double v = 0.0;
    try {
      v = node.as<double>();
    } catch (const YAML::Exception&) {
      fail(node, "'" + path + "' must be a number, got '" + node.Scalar() + "'");
    }
    if (!std::isfinite(v)) fail(node, "'" + path + "' must be finite");
    if (v < f.lo || v > f.hi) {
      fail(node, "'" + path + "' = " + node.Scalar() + " is outside [" + shown(f.lo) + ", " +
                     shown(f.hi) + "]");
    }
    return v;
  }

  int integer(const YAML::Node& node, const std::string& path, const Field& f) const {
    const double v = number(node, path, f);
    if (v != std::floor(v)) {
      fail(node, "'" + path + "' must be an integer, got '" + node.Scalar() + "'");
    }
    return static_cast<int>(v);
  }

  void read_field(const YAML::Node& node, const std::string& path, const Field& f) const {
    std::visit(
        [&](auto& target) {
          using T = std::decay_t<decltype(target)>;
          if constexpr (std::is_same_v<T, bool*>) {
            bool v = false;
            if (!node.IsScalar() || !YAML::convert<bool>::decode(node, v)) {
              fail(node, "'" + path + "' must be true or false");
            }
            *target = v;
          } else if constexpr (std::is_same_v<T, int*>) {
            *target = integer(node, path, f);
          } else if constexpr (std::is_same_v<T, float*>) {
            *target = static_cast<float>(number(node, path, f));
          } else if constexpr (std::is_same_v<T, double*>) {
            *target = number(node, path, f);
          } else if constexpr (std::is_same_v<T, Choice>) {
            if (!node.IsScalar() || !target.set(node.Scalar())) {
              fail(node, "'" + path + "' must be one of " + target.options +
                             (node.IsScalar() ? ", got '" + node.Scalar() + "'" : std::string()));
            }
          } else {
            const size_t n = target->size();
            if (!node.IsSequence() || node.size() != n) {
              fail(node, "'" + path + "' must be a list of " + std::to_string(n) + " integers");
            }
            for (size_t i = 0; i < n; ++i) {
              (*target)[i] = integer(node[i], path + "[" + std::to_string(i) + "]", f);
            }
          }
        },
        const_cast<Target&>(f.target));
  }

  void read_section(const YAML::Node& node, const std::string& path, const Section& s) const {
    if (node.IsNull()) return;  // `tracker:` with nothing under it
    if (!node.IsMap()) {
      fail(node, (path.empty() ? std::string("the file") : "'" + path + "'") + " must be a map");
    }
    std::set<std::string> seen;
    for (const auto& kv : node) {
      const YAML::Node& key_node = kv.first;
      if (!key_node.IsScalar()) fail(key_node, "keys must be names");
      const std::string key = key_node.Scalar();
      const std::string full = join(path, key);
      if (!seen.insert(key).second) fail(key_node, "'" + full + "' is given twice");
      bool known = false;
      for (const Field& f : s.fields) {
        if (key == f.key) {
          read_field(kv.second, full, f);
          known = true;
        }
      }
      for (const Section& sub : s.sections) {
        if (key == sub.key) {
          read_section(kv.second, full, sub);
          known = true;
        }
      }
      if (!known) {
        std::string names;
        for (const Field& f : s.fields) names += std::string(names.empty() ? "" : ", ") + f.key;
        for (const Section& sub : s.sections) {
          names += std::string(names.empty() ? "" : ", ") + sub.key;
        }
        fail(key_node, "unknown key '" + full + "' (known" + (path.empty() ? "" : " in " + path) +
                           ": " + names + ")");
      }
    }
  }
};

void write_section(std::ostream& out, const Section& s, int indent) {
  const std::string pad(static_cast<size_t>(indent), ' ');
  for (const Field& f : s.fields) {
    out << pad << f.key << ": ";
    std::visit(
        [&](const auto& target) {
          using T = std::decay_t<decltype(target)>;
          if constexpr (std::is_same_v<T, bool*>) {
            out << (*target ? "true" : "false");
          } else if constexpr (std::is_same_v<T, int*>) {
            out << *target;
          } else if constexpr (std::is_same_v<T, float*> || std::is_same_v<T, double*>) {
            std::string text = shown(*target);
            // Keep a decimal point so that the value reads back as a real number everywhere.
            if (text.find_first_of(".en") == std::string::npos) text += ".0";
            out << text;
          } else if constexpr (std::is_same_v<T, Choice>) {
            out << target.get();
          } else {
            out << "[";
            for (size_t i = 0; i < target->size(); ++i) out << (i ? ", " : "") << (*target)[i];
            out << "]";
          }
        },
        f.target);
    out << "\n";
  }
  for (const Section& sub : s.sections) {
    out << pad << sub.key << ":\n";
    write_section(out, sub, indent + 2);
  }
}

}  // namespace

bool read_yaml(const std::string& text, const std::string& source, bool positions,
               const Section& schema, std::string* error) {
  const Reader reader{source, positions};
  try {
    const YAML::Node root = YAML::Load(text);
    if (root.IsDefined() && !root.IsNull()) reader.read_section(root, "", schema);
  } catch (const ConfigError& e) {
    if (error) *error = e.what();
    return false;
  } catch (const YAML::Exception& e) {
    if (error) {
      *error = source;
      if (positions && e.mark.line >= 0) {
        *error += ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1);
      }
      *error += ": " + e.msg;
    }
    return false;
  }
  return true;
}

std::string write_yaml(const Section& schema) {
  std::ostringstream out;
  write_section(out, schema, 0);
  return out.str();
}

bool read_text_file(const std::string& path, std::string* text, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open the file";
    return false;
  }
  std::stringstream buffer;
  buffer << in.rdbuf();
  *text = buffer.str();
  return true;
}

}  // namespace dqo::config
