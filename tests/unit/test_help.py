"""``--help`` answers everywhere a user may type it: every ``aes-swarm`` command, every
console script and every benchmark script print their usage and exit 0.

argparse formats help texts only when asked, so a stray ``%`` in one (``bench_soak.py
--help`` once died on ``pid % 50``) is found only by asking.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from aes_ros.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
#: The bench scripts (modules without a ``__main__`` block are their helpers).
BENCH_SCRIPTS = sorted(
    p.name for p in (ROOT / "bench").glob("*.py") if '__name__ == "__main__"' in p.read_text()
)
CONSOLE_SCRIPTS = sorted(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"])


def test_every_aes_swarm_command_formats_its_help() -> None:
    parser = build_parser()
    (commands,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert len(commands.choices) >= 10
    for name, sub in commands.choices.items():
        text = sub.format_help()
        assert text.startswith(f"usage: aes-swarm {name}"), name
        assert "-h, --help" in text, name


@pytest.mark.parametrize("script", BENCH_SCRIPTS)
def test_every_bench_script_answers_help(script: str) -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "bench" / script), "--help"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("usage:"), done.stdout[:200]


@pytest.mark.parametrize("script", CONSOLE_SCRIPTS)
def test_every_console_script_answers_help(script: str) -> None:
    """rclpy ignores --help: a node script must answer it instead of starting a node
    (``aes-robot-host --help`` once ran a 100-robot host in domain 0 for minutes, and
    ``aes-dashboard --help`` served a dashboard)."""
    exe = Path(sys.executable).with_name(script)
    done = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    if script == "aes-swarm":
        assert done.stdout.startswith("usage: aes-swarm"), done.stdout[:200]
        return
    # a node's usage, or a driver's own options beside --ros-args (aes-mona-driver)
    assert done.stdout.startswith(f"usage: {script} ["), done.stdout[:200]
    assert "--ros-args" in done.stdout, done.stdout[:200]
    assert "Parameters" in done.stdout or "parameters" in done.stdout
