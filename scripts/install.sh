#!/usr/bin/env bash
# Installs wgpu-rt and everything its tests and benchmarks need on a fresh Debian/Ubuntu machine:
# a Vulkan driver (Mesa's lavapipe, when no Vulkan driver is present), CPU-only torch, and the package
# in editable mode with its extras. Safe to rerun.
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
if ! compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null \
        && ! compgen -G "/etc/vulkan/icd.d/*.json" >/dev/null; then
    echo "install: no Vulkan driver found; installing Mesa's lavapipe (mesa-vulkan-drivers)"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
fi
# The CPU build first: an unpinned torch would pull gigabytes of CUDA wheels.
python3 -m pip install -q --disable-pip-version-check torch==2.13.0
python3 -m pip install -q --disable-pip-version-check -e ".[test,train,bench]"
