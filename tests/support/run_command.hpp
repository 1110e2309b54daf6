#pragma once
// Run a shell command line (stdout and stderr merged unless the caller redirects), for tests that
// drive the real binaries as a user would.
#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace imucal::test_support {

struct CommandResult {
  int code = -1;    ///< exit status, -1 if it did not exit normally
  std::string out;  ///< what it printed
};

inline CommandResult run_command(const std::string& command_line) {
  CommandResult r;
  FILE* p = popen(command_line.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = pclose(p);
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

}  // namespace imucal::test_support
