#pragma once
// Shared exit-code policy of the command-line tools: 0 ok, 1 failure, 2 usage.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <functional>

#include "pg/core/error.h"

namespace pg {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// Parses argv into `app` and runs `body`; turns every error into a message on stderr and the
// matching exit code.
inline int run_cli(CLI::App& app, int argc, char** argv, const std::function<int()>& body) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitUsage;
  }
  try {
    return body();
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
  }
  return kExitFailure;
}

}  // namespace pg
