#!/usr/bin/env bash
# README command 1: install the dependencies, build, and run the main job on the built-in
# default: render scenes/default.json (a cube corner rocking on a DIGIT) into out/default, track
# the cube with PatchGraph from the rendered normals, then again from the colour images through
# the default learned-normals model, and print the accuracy and the speed of each
# (scripts/demo_job.sh, which the test suite runs too).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/scripts/install_deps.sh"
"$root/scripts/build.sh"
"$root/scripts/demo_job.sh"
