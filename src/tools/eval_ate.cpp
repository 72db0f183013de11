// dqo_eval_ate: absolute trajectory error of an estimate against ground truth, both TUM trajectory
// files (`t tx ty tz qx qy qz qw`). Poses are associated by timestamp, the estimate aligned by
// Umeyama (rotation + translation; --scale adds a scale), and the position errors summarised.
// The last line is `ate_rmse_m: X`, for scripts.
//
//   dqo_eval_ate EST.txt GT.txt [--max-dt S] [--scale]
#include <cstdio>
#include <cstdlib>
#include <string>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/eval/ate.h"

namespace {

constexpr char kUsage[] =
    "usage: dqo_eval_ate EST.txt GT.txt [--max-dt S] [--scale]\n"
    "  EST.txt, GT.txt  TUM trajectories: `t tx ty tz qx qy qz qw` per line, T_world_camera\n"
    "  --max-dt S       largest time difference of an associated pair, seconds (default 0.02)\n"
    "  --scale          also estimate a scale (monocular estimates; RGB-D needs none)\n"
    "Prints the matched count, rmse/mean/median/max in metres, and `ate_rmse_m: X` last.\n";

}  // namespace

int main(int argc, char** argv) {
  std::string files[2];
  int positional = 0;
  dqo::eval::AteParams params;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--scale") {
      params.with_scale = true;
    } else if (a == "--max-dt") {
      char* end = nullptr;
      const double v = i + 1 < argc ? std::strtod(argv[i + 1], &end) : 0.0;
      if (i + 1 >= argc || end == argv[i + 1] || *end != '\0' || !(v >= 0.0)) {
        std::fprintf(stderr, "dqo_eval_ate: --max-dt takes seconds >= 0\n");
        return 2;
      }
      params.max_time_difference = v;
      ++i;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "dqo_eval_ate: unknown option %s\n%s", a.c_str(), kUsage);
      return 2;
    } else if (positional < 2) {
      files[positional++] = a;
    } else {
      std::fprintf(stderr, "dqo_eval_ate: unexpected argument %s\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  if (positional != 2) {
    std::fputs(kUsage, stderr);
    return 2;
  }

  std::string error;
  const auto estimate = dqo::read_tum_trajectory(files[0], &error);
  if (!estimate) {
    std::fprintf(stderr, "dqo_eval_ate: %s\n", error.c_str());
    return 1;
  }
  const auto ground_truth = dqo::read_tum_trajectory(files[1], &error);
  if (!ground_truth) {
    std::fprintf(stderr, "dqo_eval_ate: %s\n", error.c_str());
    return 1;
  }
  const auto r = dqo::eval::compute_ate(*estimate, *ground_truth, params, &error);
  if (!r) {
    std::fprintf(stderr, "dqo_eval_ate: %s\n", error.c_str());
    return 1;
  }
  if (2 * static_cast<size_t>(r->matched) < estimate->size()) {
    std::fprintf(stderr, "dqo_eval_ate: warning: only %d of %zu estimated poses have ground truth within %g s\n",
                 r->matched, estimate->size(), params.max_time_difference);
  }
  std::printf("matched: %d of %zu estimated poses (ground truth: %zu poses, max dt %g s)\n", r->matched,
              estimate->size(), ground_truth->size(), params.max_time_difference);
  if (params.with_scale) std::printf("scale: %.6f\n", r->scale);
  std::printf("rmse_m: %.6f\nmean_m: %.6f\nmedian_m: %.6f\nmax_m: %.6f\n", r->rmse_m, r->mean_m,
              r->median_m, r->max_m);
  std::printf("ate_rmse_m: %.6f\n", r->rmse_m);
  return 0;
}
