#!/usr/bin/env bash
# Installs what Showcase needs beyond the Rust toolchain, only when missing:
# the Vulkan loader and Mesa's software Vulkan driver (lavapipe), which the
# GPU tests and the demo's renderer use on machines without a GPU, and
# Debian's Chromium, in which the web-page tests (the dashboard, the demo's
# report) run headless, and Xvfb, the X server the node window's test
# opens its real window on, and Xorg with its dummy video driver, on which
# the two-output window test opens two monitors (Xvfb has one).
set -euo pipefail

have_vulkan() {
    ldconfig -p 2>/dev/null | grep -q 'libvulkan\.so\.1' &&
        ls /usr/share/vulkan/icd.d/lvp_icd*.json >/dev/null 2>&1
}

have_chromium() {
    command -v chromium >/dev/null 2>&1 || [ -n "${CHROMIUM:-}" ]
}

have_xvfb() {
    command -v Xvfb >/dev/null 2>&1
}

have_xorg_dummy() {
    command -v Xorg >/dev/null 2>&1 && [ -e /usr/lib/xorg/modules/drivers/dummy_drv.so ]
}

if have_vulkan && have_chromium && have_xvfb && have_xorg_dummy; then
    exit 0
fi

echo "setup: installing what is missing of mesa-vulkan-drivers, libvulkan1 (software Vulkan), chromium (headless page tests), xvfb and xserver-xorg-video-dummy (the window tests)" >&2
if [ "$(id -u)" -eq 0 ]; then
    SUDO=""
elif command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
else
    echo "setup: need root (or sudo) to install mesa-vulkan-drivers libvulkan1 chromium xvfb xserver-xorg-core xserver-xorg-video-dummy" >&2
    exit 1
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
have_vulkan || $SUDO apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers libvulkan1 >/dev/null
have_chromium || $SUDO apt-get install -y -qq --no-install-recommends chromium >/dev/null
have_xvfb || $SUDO apt-get install -y -qq --no-install-recommends xvfb >/dev/null
have_xorg_dummy || $SUDO apt-get install -y -qq --no-install-recommends xserver-xorg-core xserver-xorg-video-dummy >/dev/null
have_vulkan || { echo "setup: Vulkan is still missing after the install" >&2; exit 1; }
have_chromium || { echo "setup: chromium is still missing after the install" >&2; exit 1; }
have_xvfb || { echo "setup: Xvfb is still missing after the install" >&2; exit 1; }
have_xorg_dummy || { echo "setup: Xorg's dummy video driver is still missing after the install" >&2; exit 1; }
