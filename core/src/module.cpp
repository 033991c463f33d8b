#include "pg/core/module.h"

#include <dlfcn.h>

#include <filesystem>
#include <stdexcept>
#include <vector>

namespace pg {

void* module_entry(const std::string& built_path, const char* entry, const std::string& what) {
  const std::filesystem::path built = built_path;
  std::vector<std::filesystem::path> candidates = {built};
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto beside =
        self.parent_path().parent_path() / built.parent_path().filename() / built.filename();
    if (beside != built) candidates.push_back(beside);
  }
  std::string failures;
  for (const auto& path : candidates) {
    // RTLD_LOCAL: the module's libraries stay out of the program's own symbol lookups.
    void* module = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
    const char* why = module ? nullptr : dlerror();
    void* function = module ? dlsym(module, entry) : nullptr;
    if (function) return function;
    failures += (failures.empty() ? "" : "; ") +
                (why ? std::string(why) : path.string() + ": no function " + entry);
  }
  throw std::runtime_error("cannot load " + what + " (the module " + built.filename().string() +
                           ", built in " + built.parent_path().string() + "): " + failures);
}

}  // namespace pg
