#pragma once
// Files a user asks for by name (the mapping services' save_map, load_map, extract_object; DESIGN.md
// "Messages and services") go under one configured output folder and nowhere else: a name or
// sub-folder that resolves outside it — `..`, an absolute path, a symlink that leads out — is
// refused before anything is written.

#include <optional>
#include <string>

namespace dqo {

// The absolute, normalised path of `relative` under `root` (which need not exist yet), or nullopt
// and *error when `relative` is absolute, empty where a name is needed, or resolves outside `root`
// once every symlink on the way that exists is followed. `relative` may be "" to mean the root
// itself (allow_root). Nothing is created.
std::optional<std::string> resolve_output_path(const std::string& root, const std::string& relative,
                                               std::string* error, bool allow_root = false);

}  // namespace dqo
