#!/usr/bin/env bash
# Installs what Showcase needs beyond the Rust toolchain, only when missing:
# the Vulkan loader and Mesa's software Vulkan driver (lavapipe), which the
# GPU tests and the demo's renderer use on machines without a GPU.
set -euo pipefail

have_vulkan() {
    ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1' &&
        ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1
}

if have_vulkan; then
    exit 0
fi

echo "setup: installing mesa-vulkan-drivers and libvulkan1 (software Vulkan)" >&2
if [ "$(id -u)" -eq 0 ]; then
    SUDO=""
elif command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
else
    echo "setup: need root (or sudo) to install mesa-vulkan-drivers libvulkan1" >&2
    exit 1
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers libvulkan1 >/dev/null
have_vulkan || { echo "setup: Vulkan is still missing after the install" >&2; exit 1; }
