#!/usr/bin/env bash
# README command 1: install the dependencies, build, and run the main job on the built-in
# default: render scenes/default.json (a cube corner rocking on a DIGIT) into out/default, track
# the cube with PatchGraph from the rendered normals, and print the accuracy and the speed.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh"
"$root/build/tools/tacsim" render "$root/scenes/default.json" --out "$root/out/default"
"$root/build/tools/tacsim" info "$root/out/default"
"$root/build/tools/patchgraph" track "$root/out/default" --method patchgraph --normals gt \
  --out "$root/out/default_track"
