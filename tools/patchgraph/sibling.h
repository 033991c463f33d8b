#pragma once
// patchgraph's programs run one another (tools/CMakeLists.txt): the `patchgraph` launcher runs
// patchgraph-core or patchgraph-torch, and patchgraph-core runs patchgraph-torch. What runs a
// network, and how a program runs the other, for both; no library beyond the C++ one, for the
// launcher's start-up.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

namespace pg {

// The subcommands that always run a network (in patchgraph-torch).
inline bool is_network_command(const std::string& command) {
  return command == "train-normals" || command == "eval-normals" || command == "model-info";
}

// The subcommands that run one when their --normals names a model.
inline bool takes_normals_models(const std::string& command) {
  return command == "track" || command == "eval" || command == "bench";
}

// Whether a --normals value ("gt", "shading", "MODEL" or "MODEL,MODEL,...") names anything but
// gt and shading, which need no network.
inline bool names_a_model(const std::string& normals) {
  std::size_t begin = 0;
  while (true) {
    const std::size_t end = normals.find(',', begin);
    const std::string item =
        normals.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
    if (item != "gt" && item != "shading") return true;
    if (end == std::string::npos) return false;
    begin = end + 1;
  }
}

// Replaces this process with the program `name` of this program's folder (found on the PATH
// when /proc does not give the folder), with the same arguments: the same process id, streams
// and exit code. Returns only if that fails, with "PROGRAM: cannot run it (REASON); ...".
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
  return program + ": cannot run it (" + std::strerror(errno) +
         "); patchgraph runs its commands in patchgraph-core and patchgraph-torch (LibTorch): "
         "build them with it (cmake --build build) and keep the three programs in one folder";
}

}  // namespace pg
