#pragma once
// bench_tracking --real (bench_tracking_real.cpp): real data and injected faults.
#include <string>

struct RealOptions {
  std::string tum_dir;           // "" : <source>/../shared/data/tum_fr1_xyz
  int synthetic_frames = 150;    // of the tabletop (5 s at 30 Hz)
  bool verbose = false;          // one line per frame
  std::string only;              // one fault ("covered", "no depth", "jump 30deg", "repeated")
  // > 0: only TUM at every `every`-th frame, `repeat` times over (a quick timing or profiling
  // loop: ten frames at every 20th give a noisy median, and a profiler wants more of them).
  int every = 0;
  int repeat = 1;
};

// Prints one row per run; 0 when no wrong pose was reported ok.
int run_real_benchmark(const std::string& source_dir, const RealOptions& options);
