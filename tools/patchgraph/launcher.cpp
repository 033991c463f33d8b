// patchgraph: picks the program that runs the command line (tools/CMakeLists.txt) and runs it in
// this process (exec: the same process id, arguments, streams and exit code).
//   patchgraph-torch  the whole program, with LibTorch: the commands that run a network
//                     (train-normals, eval-normals, model-info; track, eval or bench with a
//                     --normals model);
//   patchgraph-core   the same without LibTorch, whose libraries take about 0.6 s to load at
//                     every start: every other command.
// This program links neither, so it starts in a millisecond. It reads the words of the command
// line only; patchgraph-core parses them and hands a network's command that this reading missed
// to patchgraph-torch itself (tools/patchgraph/main.cpp).
#include <cstdio>
#include <cstring>
#include <string>

#include "sibling.h"

namespace {

// Whether a --normals value ("gt", "MODEL" or "MODEL,MODEL,...") names anything but gt.
bool names_a_model(const std::string& value) {
  std::size_t begin = 0;
  while (true) {
    const std::size_t end = value.find(',', begin);
    if (value.substr(begin, end == std::string::npos ? std::string::npos : end - begin) != "gt")
      return true;
    if (end == std::string::npos) return false;
    begin = end + 1;
  }
}

bool runs_a_network(int argc, char** argv) {
  int i = 1;
  while (i < argc && argv[i][0] == '-') ++i;  // --help, --version: they take no value
  if (i == argc) return false;
  const std::string command = argv[i];
  if (command == "train-normals" || command == "eval-normals" || command == "model-info") {
    return true;
  }
  if (command != "track" && command != "eval" && command != "bench") return false;
  for (++i; i < argc; ++i) {
    const std::string word = argv[i];
    if (word.rfind("--normals=", 0) == 0) {
      if (names_a_model(word.substr(std::strlen("--normals=")))) return true;
    } else if (word == "--normals") {
      // Its values (bench takes several) up to the next option.
      for (; i + 1 < argc && argv[i + 1][0] != '-'; ++i) {
        if (names_a_model(argv[i + 1])) return true;
      }
    }
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  const char* name = runs_a_network(argc, argv) ? PG_NETWORK_PROGRAM : PG_CORE_PROGRAM;
  const std::string failed = pg::exec_sibling(name, argv);
  std::fprintf(stderr,
               "error: %s; patchgraph runs its commands in it: build it with patchgraph (cmake "
               "--build build), and keep the three programs (patchgraph, %s, %s) in one "
               "folder\n",
               failed.c_str(), PG_CORE_PROGRAM, PG_NETWORK_PROGRAM);
  return 1;
}
