#!/usr/bin/env bash
# Configures and builds (Release by default) into build/. Usage: scripts/build.sh [cmake args...]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cmake -S "$root" -B "$root/build" -DCMAKE_BUILD_TYPE="${BUILD_TYPE:-Release}" "$@"
cmake --build "$root/build" -j "$(nproc)"
