#!/usr/bin/env bash
# README command 2: install the dependencies, build from scratch, run the whole test suite.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh" -DPG_BUILD_TESTS=ON
cd "$root/build"
ctest --output-on-failure -j "$(nproc)"
