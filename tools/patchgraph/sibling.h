#pragma once
// patchgraph's programs run one another (tools/CMakeLists.txt): the `patchgraph` launcher runs
// patchgraph-core or patchgraph-torch, and patchgraph-core runs patchgraph-torch. No library
// beyond the C++ one, for the launcher's start-up.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

namespace pg {

// Replaces this process with the program `name` of this program's folder (found on the PATH
// when /proc does not give the folder), with the same arguments: the same process id, streams
// and exit code. Returns only if that fails, with "PROGRAM: cannot run it (REASON)".
inline std::string exec_sibling(const char* name, char** argv) {
  char self[4096];
  const ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
  const std::string path = n > 0 ? std::string(self, std::size_t(n)) : "";
  const std::string program = path.empty() ? name : path.substr(0, path.rfind('/') + 1) + name;
  std::fflush(nullptr);
  if (path.empty()) {
    execvp(name, argv);
  } else {
    execv(program.c_str(), argv);
  }
  return program + ": cannot run it (" + std::strerror(errno) + ")";
}

}  // namespace pg
