#pragma once
// A progress line for long command-line jobs: a bar redrawn in place on a terminal, a plain line
// every 10 % otherwise (logs, CI), so that neither floods the output.

#include <chrono>
#include <cstdio>
#include <string>

#include <unistd.h>

namespace dqo {

class ProgressBar {
 public:
  ProgressBar(std::string label, int total, std::FILE* out = stderr)
      : label_(std::move(label)), total_(total), out_(out), tty_(isatty(fileno(out)) != 0),
        start_(std::chrono::steady_clock::now()) {}

  void update(int done) {
    const double elapsed = seconds();
    const double rate = elapsed > 0.0 ? done / elapsed : 0.0;
    const double eta = rate > 0.0 ? (total_ - done) / rate : 0.0;
    const int percent = total_ > 0 ? done * 100 / total_ : 100;
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = total_ > 0 ? done * kWidth / total_ : kWidth;
      std::fprintf(out_, "\r%s [%s%s] %d/%d  %.1f/s  ETA %.0f s ", label_.c_str(),
                   std::string(filled, '#').c_str(), std::string(kWidth - filled, '.').c_str(), done,
                   total_, rate, eta);
      if (done >= total_) std::fprintf(out_, "\n");
      std::fflush(out_);
    } else if (percent / 10 > last_decile_ || done >= total_) {
      last_decile_ = percent / 10;
      std::fprintf(out_, "%s %d/%d (%d %%)  %.1f/s  ETA %.0f s\n", label_.c_str(), done, total_, percent,
                   rate, eta);
      std::fflush(out_);
    }
  }

  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::string label_;
  int total_;
  std::FILE* out_;
  bool tty_;
  int last_decile_ = 0;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace dqo
