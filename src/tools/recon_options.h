#pragma once
// The sampling options shared by dqo_eval_recon and dqo_recon_table (--samples N, --seed S).

#include <cerrno>
#include <cstdlib>
#include <string>

#include "dqo_map/mesh/recon_metrics.h"

namespace dqo::tools {

inline bool parse_u64(const char* text, unsigned long long* out) {
  if (text[0] == '-' || text[0] == '\0') return false;
  char* end = nullptr;
  errno = 0;
  *out = std::strtoull(text, &end, 10);
  return errno == 0 && end != text && *end == '\0';
}

// argv[*i] is --samples or --seed: takes its value (advancing *i) into *params. False when argv[*i]
// is neither; *usage_error is set when it is one with a bad or missing value.
inline bool parse_recon_option(int argc, char** argv, int* i, mesh::ReconParams* params,
                               std::string* usage_error) {
  const std::string a = argv[*i];
  if (a != "--samples" && a != "--seed") return false;
  unsigned long long v = 0;
  const bool ok = *i + 1 < argc && parse_u64(argv[*i + 1], &v);
  if (a == "--samples") {
    if (!ok || v < 1 || v > 100000000) {
      *usage_error = "--samples takes an integer from 1 to 100000000";
      return true;
    }
    params->samples = static_cast<int>(v);
  } else {
    if (!ok) {
      *usage_error = "--seed takes a non-negative integer";
      return true;
    }
    params->seed = v;
  }
  ++*i;
  return true;
}

}  // namespace dqo::tools
