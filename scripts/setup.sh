#!/usr/bin/env bash
# Install aes-swarm and everything it needs into ./.venv (fresh machine: Python 3.11 + pip).
# ROS 2 Jazzy comes from PyPI wheels; no system ROS install is needed.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test]"
echo "aes-swarm installed in $(pwd)/.venv (activate with: . .venv/bin/activate)"
