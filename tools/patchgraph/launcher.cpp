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

bool runs_a_network(int argc, char** argv) {
  int i = 1;
  while (i < argc && argv[i][0] == '-') ++i;  // --help, --version: they take no value
  if (i == argc) return false;
  const std::string command = argv[i];
  if (pg::is_network_command(command)) return true;
  if (!pg::takes_normals_models(command)) return false;
  for (++i; i < argc; ++i) {
    const std::string word = argv[i];
    if (word.rfind("--normals=", 0) == 0) {
      if (pg::names_a_model(word.substr(std::strlen("--normals=")))) return true;
    } else if (word == "--normals") {
      // Its values (bench takes several) up to the next option.
      for (; i + 1 < argc && argv[i + 1][0] != '-'; ++i) {
        if (pg::names_a_model(argv[i + 1])) return true;
      }
    }
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  const char* name = runs_a_network(argc, argv) ? PG_NETWORK_PROGRAM : PG_CORE_PROGRAM;
  std::fprintf(stderr, "error: %s\n", pg::exec_sibling(name, argv).c_str());
  return 1;
}
