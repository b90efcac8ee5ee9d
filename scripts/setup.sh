#!/usr/bin/env bash
# Install aes-swarm and everything it needs into ./.venv (fresh machine: Python 3.11 + pip).
# ROS 2 Jazzy comes from PyPI wheels; no system ROS install is needed.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test,bench]"
# Debian packages some tests need, installed when missing and we are root (quietly; without
# apt those tests skip with a reason): nftables injects packet loss in
# tests/system/test_multihost.py; chromium and chromium-driver drive the dashboard in
# tests/system/test_dashboard_browser.py (the system browser: nothing is downloaded at run time).
missing=()
command -v nft >/dev/null 2>&1 || missing+=(nftables)
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
command -v chromedriver >/dev/null 2>&1 || missing+=(chromium-driver)
# the Mona firmware (firmware/) and its simulated MCU: tests/system/test_firmware.py
command -v avr-gcc >/dev/null 2>&1 || missing+=(gcc-avr avr-libc)
{ command -v cc && command -v make; } >/dev/null 2>&1 || missing+=(gcc make)
[ -e /usr/include/simavr/sim_avr.h ] || missing+=(simavr libsimavr-dev libelf-dev pkg-config)
if [ "${#missing[@]}" -gt 0 ] && [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    if ! { timeout 300 apt-get update -qq &&
        DEBIAN_FRONTEND=noninteractive timeout 600 apt-get install -y -qq \
            --no-install-recommends "${missing[@]}"; } >/dev/null 2>&1; then
        echo "setup: could not install ${missing[*]}; the tests that need them will be skipped" >&2
    fi
fi
if command -v avr-gcc >/dev/null 2>&1 && [ -e /usr/include/simavr/sim_avr.h ]; then
    make -s -C firmware >/dev/null 2>&1 ||
        echo "setup: make -C firmware failed; the firmware tests will fail until it builds" >&2
fi
# numba's kernels into their cache now, not at the first simulation, bridge or test
.venv/bin/python -m aes_ros.precompile
echo "aes-swarm installed in $(pwd)/.venv (activate with: . .venv/bin/activate)"
