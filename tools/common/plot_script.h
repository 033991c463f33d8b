#pragma once
// Runs one of the repository's matplotlib scripts (tools/*.py) on an output folder.
#include <spawn.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

extern char** environ;

namespace pg {

// `/usr/bin/python3 PG_SOURCE_DIR/tools/<script> <out_dir>`: Debian's interpreter, where
// python3-matplotlib is installed (not a user's own python3), started with its arguments as they
// are (no shell: an --out of any name is one argument, never a command). On failure warns on
// stderr, with the script's exit status, and returns false: a missing plot does not fail the run.
inline bool run_plot_script(const std::string& script, const std::string& out_dir) {
  const std::string python = "/usr/bin/python3";
  const std::string path = (std::filesystem::path(PG_SOURCE_DIR) / "tools" / script).string();
  char* argv[] = {const_cast<char*>(python.c_str()), const_cast<char*>(path.c_str()),
                  const_cast<char*>(out_dir.c_str()), nullptr};
  std::fflush(stdout);  // the script's output follows ours
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, python.c_str(), nullptr, nullptr, argv, environ);
  int status = 0;
  if (spawned == 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) &&
      WEXITSTATUS(status) == 0) {
    return true;
  }
  const std::string why =
      spawned != 0        ? std::string("cannot start ") + python + ": " + std::strerror(spawned)
      : WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                          : std::string("killed by a signal");
  std::fprintf(stderr,
               "warning: plot not made (%s %s %s: %s; its error is above, if any; the plots need "
               "python3-matplotlib)\n",
               python.c_str(), path.c_str(), out_dir.c_str(), why.c_str());
  return false;
}

}  // namespace pg
