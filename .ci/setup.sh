#!/usr/bin/env bash
# Installs what citywalk needs on a fresh Debian/Ubuntu machine with no GPU:
# Mesa's software Vulkan (lavapipe) and GL (llvmpipe) for wgpu, the Vulkan loader, Xvfb for
# the windowed-viewer test, Chromium for the CesiumJS check of the export, and the Rust
# components CI uses. Safe to run again.
set -euo pipefail

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "setup: not root and no sudo; install these packages yourself:" \
      "mesa-vulkan-drivers libvulkan1 libegl1 libegl-mesa0 libgl1-mesa-dri xvfb xauth fonts-dejavu-core nodejs npm chromium" >&2
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
# Debian's Chromium runs CesiumJS headless (.ci/cesium-check), WebGL in software (SwiftShader,
# shipped with it); without its recommends (a desktop's worth of packages CI doesn't need).
if [ ! -x /usr/bin/chromium ] && { [ -n "$SUDO" ] || [ "$(id -u)" -eq 0 ]; }; then
  echo "setup: installing chromium" >&2
  [ "${#missing[@]}" -gt 0 ] || $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends chromium \
    >/dev/null
fi

if command -v rustup >/dev/null 2>&1; then
  rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi

# The Khronos glTF validator and loaders.gl (.ci/export-check, for tests/tests/export_3dtiles.rs)
# and CesiumJS with playwright-core (.ci/cesium-check, for tests/tests/export_cesium.rs), pinned
# by their package-lock.json. Installed again when a lock file changes.
for check in "$(dirname "$0")/export-check" "$(dirname "$0")/cesium-check"; do
  if command -v npm >/dev/null 2>&1 \
    && { [ ! -d "$check/node_modules" ] || [ "$check/package-lock.json" -nt "$check/node_modules" ]; }; then
    echo "setup: npm ci in $check" >&2
    npm ci --prefix "$check" --no-audit --no-fund --loglevel=error >/dev/null
    touch "$check/node_modules"
  fi
done
