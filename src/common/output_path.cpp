#include "dqo_map/common/output_path.h"

#include <filesystem>
#include <system_error>

namespace dqo {
namespace {

namespace fs = std::filesystem;

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

// True when `p` is `root` or below it (both absolute and normalised).
bool is_within(const fs::path& root, const fs::path& p) {
  auto r = root.begin(), q = p.begin();
  for (; r != root.end(); ++r, ++q) {
    if (r->empty()) continue;  // the empty element a trailing separator leaves
    if (q == p.end() || *r != *q) return false;
  }
  return true;
}

}  // namespace

std::optional<std::string> resolve_output_path(const std::string& root, const std::string& relative,
                                               std::string* error, bool allow_root) {
  if (root.empty()) {
    fail(error, "no output folder configured");
    return std::nullopt;
  }
  const fs::path rel(relative);
  if (relative.empty() && !allow_root) {
    fail(error, "a file name is needed");
    return std::nullopt;
  }
  if (rel.is_absolute() || rel.has_root_name() || rel.has_root_directory()) {
    fail(error, "'" + relative + "' is an absolute path: names are relative to the output folder");
    return std::nullopt;
  }
  std::error_code ec;
  // weakly_canonical follows the symlinks of the part that exists and normalises the rest, so both
  // `a/../../x` and a symlink `a -> /etc` are seen for where they lead.
  const fs::path base = fs::weakly_canonical(fs::absolute(root, ec), ec);
  if (ec) {
    fail(error, "output folder " + root + ": " + ec.message());
    return std::nullopt;
  }
  const fs::path target = fs::weakly_canonical(base / rel, ec);
  if (ec) {
    fail(error, "'" + relative + "': " + ec.message());
    return std::nullopt;
  }
  if (!is_within(base, target)) {
    fail(error, "'" + relative + "' resolves to " + target.string() + ", outside the output folder " +
                    base.string());
    return std::nullopt;
  }
  if (!allow_root && target == base) {
    fail(error, "'" + relative + "' names the output folder itself, not a file in it");
    return std::nullopt;
  }
  return target.string();
}

}  // namespace dqo
