#!/usr/bin/env bash
# Installs the build and run-time dependencies from Debian 12's packages.
# libopenblas0-openmp: LibTorch's transposed convolutions are BLAS matrix products, and a minimal
# install would otherwise get the unoptimised reference BLAS (ATLAS -> OpenBLAS alone made the
# default U-Net's inference 1.2x faster here). patchgraph links it ahead of the ATLAS that Ceres
# brings in (tools/CMakeLists.txt), or ATLAS would still answer them.
# libav*-dev: `patchgraph recording --video` decodes video files with FFmpeg's libraries; the
# ffmpeg command makes the tests' videos (and a user's lossless re-encodes, docs).
set -euo pipefail
packages=(
  cmake g++ make pkg-config
  libeigen3-dev nlohmann-json3-dev libopenimageio-dev libpng-dev libopenexr-dev
  libembree-dev libtinygltf-dev
  libglm-dev libceres-dev libfftw3-dev libnanoflann-dev libtbb-dev
  libcli11-dev libgtest-dev libbenchmark-dev libtorch-dev libopenblas0-openmp zlib1g-dev
  libavformat-dev libavcodec-dev libswscale-dev libavutil-dev ffmpeg
  python3-matplotlib
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages already installed"
  exit 0
fi
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
echo "install_deps: installing ${missing[*]}"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
