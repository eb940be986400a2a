// SPDX-License-Identifier: Apache-2.0
// The progress bar of `erg run`, `erg watch` and `erg fetch`, drawn on
// stderr: redrawn in place on a terminal, a line per 10% in logs and CI.
#pragma once

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>

namespace erg::client {

// "1:02:03", "2:03"; "--:--" when unknown.
inline std::string fmt_duration(double s) {
  if (!(s >= 0) || s > 1e8) return "--:--";
  const long t = static_cast<long>(s + 0.5);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

// "512 B", "1.5 KiB", "12.3 MiB", "2.00 GiB".
inline std::string fmt_bytes(double b) {
  static const char* const kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (b >= 1024 && u < 4) {
    b /= 1024;
    ++u;
  }
  char buf[32];
  if (u == 0)
    std::snprintf(buf, sizeof buf, "%.0f B", b);
  else
    std::snprintf(buf, sizeof buf, b < 10 ? "%.2f %s" : "%.1f %s", b, kUnits[u]);
  return buf;
}

class ProgressBar {
 public:
  ProgressBar() : tty_(::isatty(STDERR_FILENO) == 1) {}

  // Steps of a run.
  // `years`: simulated time (negative: not known).
  void update(long long step, long long steps, double rate, double eta, double years = -1) {
    const double frac = steps > 0 ? static_cast<double>(step) / static_cast<double>(steps) : 1.0;
    char sim[48] = "";
    if (years >= 0) std::snprintf(sim, sizeof sim, "  %.3g years", years);
    char line[256];
    std::snprintf(line, sizeof line,
                  "step %lld/%lld%s [%s] %3d%%  %.2f steps/s  ETA %s  snapshots %d", step, steps,
                  sim, bar(frac).c_str(), static_cast<int>(frac * 100), rate,
                  fmt_duration(eta).c_str(), snapshots_);
    draw(frac, line);
  }

  // Bytes of a download named `label`.
  void update_bytes(const std::string& label, long long done, long long total, double bytes_per_s) {
    const double frac = total > 0 ? static_cast<double>(done) / static_cast<double>(total) : 1.0;
    const double eta = bytes_per_s > 0 ? static_cast<double>(total - done) / bytes_per_s : -1;
    char line[320];
    std::snprintf(line, sizeof line, "%s %s/%s [%s] %3d%%  %s/s  ETA %s", label.c_str(),
                  fmt_bytes(static_cast<double>(done)).c_str(),
                  fmt_bytes(static_cast<double>(total)).c_str(), bar(frac).c_str(),
                  static_cast<int>(frac * 100), fmt_bytes(bytes_per_s).c_str(),
                  fmt_duration(eta).c_str());
    draw(frac, line);
  }

  void snapshot() { ++snapshots_; }

  // A line of its own (an event) without breaking the bar: on a terminal
  // the bar is cleared, the line printed and the bar drawn again below it.
  void note(const std::string& text) {
    if (tty_ && drawn_) {
      std::cerr << "\r\033[K" << text << "\n" << last_ << "\033[K" << std::flush;
    } else {
      std::cerr << text << "\n" << std::flush;
    }
  }

  void finish() {
    if (tty_ && drawn_) std::cerr << "\n";
    drawn_ = false;
  }
  // Keeps the worker's own stderr lines from landing inside the bar.
  bool tty() const { return tty_; }

 private:
  static std::string bar(double frac) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(std::fmin(std::fmax(frac, 0.0), 1.0) * kWidth);
    std::string b(static_cast<size_t>(filled), '#');
    b.resize(kWidth, '.');
    return b;
  }

  void draw(double frac, const std::string& line) {
    if (!tty_) {
      // Logs and CI: a line per 10%.
      const int decile = static_cast<int>(std::floor(frac * 10 + 1e-9));
      if (decile <= last_decile_) return;
      last_decile_ = decile;
    }
    std::cerr << (tty_ ? "\r" : "") << line << (tty_ ? "\033[K" : "\n") << std::flush;
    last_ = line;
    drawn_ = true;
  }

  bool tty_;
  bool drawn_ = false;
  int last_decile_ = -1;
  int snapshots_ = 0;
  std::string last_;
};

}  // namespace erg::client
