#pragma once
// A progress line on stderr for long commands: "NAME: done/total UNIT, elapsed, time left",
// rewritten in place on a terminal, one line per update otherwise (logs, CI).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace imucal::tools::imucal {

class ProgressLine {
 public:
  ProgressLine(std::string name, std::string unit)
      : name_(std::move(name)),
        unit_(std::move(unit)),
        tty_(isatty(2)),
        t0_(std::chrono::steady_clock::now()) {}
  void operator()(int done, int total) const {
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
    std::fprintf(stderr, "%s%s: %d/%d %s, %.0f s, about %.0f s left%s", tty_ ? "\r" : "",
                 name_.c_str(), done, total, unit_.c_str(), el,
                 done > 0 ? el / done * (total - done) : 0.0, tty_ ? "   " : "\n");
    if (tty_ && done == total) std::fprintf(stderr, "\n");
  }

 private:
  std::string name_, unit_;
  bool tty_;
  std::chrono::steady_clock::time_point t0_;
};

}  // namespace imucal::tools::imucal
