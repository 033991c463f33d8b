#pragma once
// A progress line for long jobs: frames done, rate, ETA. On a terminal it redraws one line;
// otherwise (CI logs) it prints a line every 10%. Each update is also where a job stops on
// Ctrl-C (stop.h), shown or not.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "stop.h"

namespace pg {

class Progress {
 public:
  // `unit` names what is counted ("frames" prints a rate in fps).
  Progress(std::string label, int total, bool enabled = true, std::string unit = "frames")
      : label_(std::move(label)), unit_(std::move(unit)), total_(total), enabled_(enabled),
        tty_(isatty(fileno(stderr))), start_(std::chrono::steady_clock::now()) {}

  // Throws Stopped when SIGINT or SIGTERM has come.
  void update(int done) {
    stop_if_asked();
    if (!enabled_ || total_ <= 0) return;
    const auto now = std::chrono::steady_clock::now();
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const bool last = done >= total_;
    if (tty_) {
      if (!last && std::chrono::duration<double>(now - last_draw_).count() < 0.1) return;
    } else {
      const int decile = done * 10 / total_;
      if (!last && decile == last_decile_) return;
      last_decile_ = decile;
    }
    last_draw_ = now;
    const std::string rate_unit = unit_ == "frames" ? "fps" : unit_ + "/s";
    // Rate and ETA once a twentieth of a second has passed: a first step done at once (its work
    // done before the line started) would read as millions per second.
    char rate[64] = "-", eta[64] = "-";
    if (elapsed >= 0.05 && done > 0) {
      std::snprintf(rate, sizeof rate, "%.1f", done / elapsed);
      std::snprintf(eta, sizeof eta, "%.1f", (total_ - done) * elapsed / done);
    }
    std::fprintf(stderr, "%s%s %d/%d %s  %s %s  ETA %s s%s", tty_ ? "\r" : "", label_.c_str(), done,
                 total_, unit_.c_str(), rate, rate_unit.c_str(), eta, tty_ && !last ? "   " : "\n");
    std::fflush(stderr);
  }

 private:
  std::string label_, unit_;
  int total_;
  bool enabled_, tty_;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_, last_draw_{};
};

}  // namespace pg
