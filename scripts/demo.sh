#!/usr/bin/env bash
# README command 1: install the dependencies, build, and run the main job on the built-in
# default: render scenes/default.json (a cube corner rocking on a DIGIT) into out/default, track
# the cube with PatchGraph from the rendered normals, then again from the colour images through
# the default learned-normals model, and print the accuracy and the speed of each.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh"
"$root/build/tools/tacsim" render "$root/scenes/default.json" --out "$root/out/default"
"$root/build/tools/tacsim" info "$root/out/default"
echo
echo "== tracking from the ground-truth normals"
"$root/build/tools/patchgraph" track "$root/out/default" --method patchgraph --normals gt \
  --out "$root/out/default_track"
echo
echo "== tracking from the colour images (learned normals: models/normals_unet.pt)"
"$root/build/tools/patchgraph" track "$root/out/default" --method patchgraph \
  --normals "$root/models/normals_unet.pt" --out "$root/out/default_track_learned"
