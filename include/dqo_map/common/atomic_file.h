#pragma once
// Whole-file writes that a crash cannot leave half done: for the map file, Gaussian PLY files and
// the offline runner's reports.

#include <string>

namespace dqo {

// Writes `bytes` to a temporary sibling of `path` (`path.tmp-<pid>`), flushes it to the disk and
// renames it over `path`: a crash or a full disk leaves the old file (or none), never half of the
// new one. False and *error (naming the file and the system's reason) on failure; the temporary
// is removed then.
bool write_file_atomically(const std::string& path, const std::string& bytes, std::string* error);

}  // namespace dqo
