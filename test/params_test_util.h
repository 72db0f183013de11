#pragma once
// Shared by the tests of the modules' YAML configurations (config/*.yaml): how many fields a params
// struct has and how many keys each section of the written YAML holds, so that a field added to a
// struct but not to its schema table fails a test that names the table.

#include <cstddef>
#include <map>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace dqo::test {

// The number of initialisers an aggregate takes (a member array counts once per element).
struct AnyValue {
  template <typename T>
  constexpr operator T() const noexcept;  // never defined: only used in unevaluated contexts
};
template <typename T, typename Seq, typename = void>
struct InitialisableWith : std::false_type {};
template <typename T, size_t... I>
struct InitialisableWith<T, std::index_sequence<I...>, std::void_t<decltype(T{(void(I), AnyValue{})...})>>
    : std::true_type {};
template <typename T, size_t N = 0>
constexpr size_t initialisers() {
  if constexpr (InitialisableWith<T, std::make_index_sequence<N + 1>>::value) {
    return initialisers<T, N + 1>();
  } else {
    return N;
  }
}

// Scalar keys per section path ("tracker.orb") of block-style YAML as config::write_yaml writes it.
inline std::map<std::string, size_t> keys_per_section(const std::string& yaml) {
  std::map<std::string, size_t> counts;
  std::vector<std::string> stack;
  std::istringstream in(yaml);
  std::string line;
  while (std::getline(in, line)) {
    const size_t indent = line.find_first_not_of(' ');
    stack.resize(indent / 2);
    const std::string key = line.substr(indent, line.find(':') - indent);
    std::string path;
    for (const auto& s : stack) path += (path.empty() ? "" : ".") + s;
    if (line.back() == ':') {
      stack.push_back(key);
      counts[path.empty() ? key : path + "." + key];  // a section, maybe with sections only
    } else {
      ++counts[path];
    }
  }
  return counts;
}

}  // namespace dqo::test
