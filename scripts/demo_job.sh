#!/usr/bin/env bash
# The main job of README command 1 (scripts/demo.sh), on a build that exists: render
# scenes/default.json (a cube corner rocking on a DIGIT), track the cube with PatchGraph from the
# rendered normals, then again from the colour images through the default learned-normals model,
# and through the inverse of the sensor's shading (no network), and print the accuracy and the
# speed of each.
#
#   scripts/demo_job.sh [BUILD_DIR] [OUT_DIR]     (defaults: build/ and out/ of the repository)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
out="${2:-$root/out}"
"$build/tools/tacsim" render "$root/scenes/default.json" --out "$out/default"
"$build/tools/tacsim" info "$out/default"
echo
echo "== tracking from the ground-truth normals"
"$build/tools/patchgraph" track "$out/default" --method patchgraph --normals gt \
  --out "$out/default_track"
echo
echo "== tracking from the colour images (learned normals: models/normals_unet.pt)"
"$build/tools/patchgraph" track "$out/default" --method patchgraph \
  --normals "$root/models/normals_unet.pt" --out "$out/default_track_learned"
echo
echo "== tracking from the colour images (no network: the sensor's shading inverted)"
"$build/tools/patchgraph" track "$out/default" --method patchgraph --normals shading \
  --out "$out/default_track_shading"
