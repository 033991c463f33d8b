#pragma once
// Runs one of the repository's matplotlib scripts (tools/*.py) on an output folder.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace pg {

// `/usr/bin/python3 PG_SOURCE_DIR/tools/<script> <out_dir>`: Debian's interpreter, where
// python3-matplotlib is installed (not a user's own python3). On failure warns on stderr and
// returns false: a missing plot does not fail the run.
inline bool run_plot_script(const std::string& script, const std::string& out_dir) {
  const std::filesystem::path path = std::filesystem::path(PG_SOURCE_DIR) / "tools" / script;
  const std::string cmd = "/usr/bin/python3 '" + path.string() + "' '" + out_dir + "'";
  if (std::system(cmd.c_str()) == 0) return true;
  std::fprintf(stderr, "warning: plot not made (%s failed; is python3-matplotlib installed?)\n",
               cmd.c_str());
  return false;
}

}  // namespace pg
