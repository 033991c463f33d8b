#!/usr/bin/env bash
# README command 1: install the dependencies, build, and run the main job on the built-in
# default: render scenes/default.json into out/default and describe the dataset.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh"
"$root/build/tools/tacsim" render "$root/scenes/default.json" --out "$root/out/default"
"$root/build/tools/tacsim" info "$root/out/default"
