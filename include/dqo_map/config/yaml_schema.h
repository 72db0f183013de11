#pragma once
// One strict YAML reader/writer for every module's parameter structs (tracking, objects, ...).
// A module describes its parameters once, as a tree of Sections whose Fields point into a params
// struct; read_yaml() and write_yaml() both walk that tree, so a field added to the table is read
// and written alike, and a test can check that the shipped config file lists every field.
//
// Strict: an unknown key, a key given twice, a value of the wrong type or outside its bounds is an
// error "SOURCE:LINE:COLUMN: message" naming the key's full path (tracker.orb.num_features).
// yaml-cpp stays in the .cpp file.
#include <array>
#include <functional>
#include <limits>
#include <string>
#include <variant>
#include <vector>

namespace dqo::config {

// A value chosen from named options (an enum): `set` returns false for a name it does not know.
struct Choice {
  std::function<bool(const std::string&)> set;
  std::function<std::string()> get;
  std::string options;  // for messages: "iou, qd, iou+qd"
};

// Builds a Choice over an enum with the usual parse/name function pair.
template <typename Enum>
Choice make_choice(Enum* target, bool (*parse)(const std::string&, Enum*),
                   const char* (*name)(Enum), std::string options) {
  return Choice{[target, parse](const std::string& text) { return parse(text, target); },
                [target, name]() { return std::string(name(*target)); }, std::move(options)};
}

using Target = std::variant<int*, float*, double*, bool*, std::array<int, 4>*, Choice>;

struct Field {
  const char* key;
  Target target;
  double lo = -std::numeric_limits<double>::infinity();  // inclusive bounds for numbers
  double hi = std::numeric_limits<double>::infinity();
};

struct Section {
  const char* key;  // "" for the root
  std::vector<Field> fields;
  std::vector<Section> sections;
};

constexpr double kInf = std::numeric_limits<double>::infinity();

// Parses `text` into the targets of `schema` (keys absent from the text keep their values).
// `source` names the text in messages; with positions = false they carry no line and column (text
// generated from ROS parameters). On error returns false with *error set; targets may then be
// partly written, so callers parse into a copy and keep it only on success.
bool read_yaml(const std::string& text, const std::string& source, bool positions,
               const Section& schema, std::string* error);

// Every field of the schema as YAML text that read_yaml reads back to the same values.
std::string write_yaml(const Section& schema);

// The whole file at `path`; false and *error ("PATH: cannot open the file") when it cannot be read.
bool read_text_file(const std::string& path, std::string* text, std::string* error);

}  // namespace dqo::config
