#!/usr/bin/env bash
# Installs what citywalk needs on a fresh Debian/Ubuntu machine with no GPU:
# Mesa's software Vulkan (lavapipe) and GL (llvmpipe) for wgpu, the Vulkan loader, Xvfb for
# the windowed-viewer test, and the Rust components CI uses. Safe to run again.
set -euo pipefail

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "setup: not root and no sudo; install these packages yourself:" \
      "mesa-vulkan-drivers libvulkan1 libegl1 libegl-mesa0 libgl1-mesa-dri xvfb xauth fonts-dejavu-core nodejs npm" >&2
  fi
fi

packages=(mesa-vulkan-drivers libvulkan1 libegl1 libegl-mesa0 libgl1-mesa-dri xvfb xauth
  fonts-dejavu-core)
# Node.js runs the ecosystem's own checks of the 3D Tiles export (.ci/export-check); a machine
# with node from elsewhere keeps it.
command -v node >/dev/null 2>&1 || packages+=(nodejs npm)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ] && { [ -n "$SUDO" ] || [ "$(id -u)" -eq 0 ]; }; then
  echo "setup: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if command -v rustup >/dev/null 2>&1; then
  rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi

# The Khronos glTF validator and loaders.gl, pinned by .ci/export-check/package-lock.json, for
# the export tests (tests/tests/export_3dtiles.rs). Installed again when the lock file changes.
check="$(dirname "$0")/export-check"
if command -v npm >/dev/null 2>&1 \
  && { [ ! -d "$check/node_modules" ] || [ "$check/package-lock.json" -nt "$check/node_modules" ]; }; then
  echo "setup: npm ci in $check" >&2
  npm ci --prefix "$check" --no-audit --no-fund --loglevel=error >/dev/null
  touch "$check/node_modules"
fi
