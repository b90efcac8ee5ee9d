"""docs/cli.md, docs/interface.md and tests/README.md show exactly what the code defines.

All three are generated (``scripts/make_reference.py``); a flag, topic, service, node
parameter or test import added, removed or renamed without regenerating fails here.
"""

from __future__ import annotations

import argparse
import difflib
import re
import subprocess
import sys
from pathlib import Path

from aes_ros.cli import build_parser
from aes_ros.cli.reference import cli_markdown, subcommands, visible_actions
from aes_ros.ros import interface

ROOT = Path(__file__).resolve().parents[2]
REGENERATE = "run: .venv/bin/python scripts/make_reference.py"


def _diff(old: str, new: str) -> str:
    lines = difflib.unified_diff(old.splitlines(), new.splitlines(), "on disk", "from code", n=0)
    return "\n".join(list(lines)[:40])


def test_cli_md_shows_every_flag_and_only_those() -> None:
    on_disk = (ROOT / "docs" / "cli.md").read_text()
    assert on_disk == cli_markdown(), f"docs/cli.md is stale; {REGENERATE}\n" + _diff(
        on_disk, cli_markdown()
    )


def test_cli_md_tables_name_each_visible_flag_of_each_command() -> None:
    """The generator itself: every flag a user can give is in its command's table, and
    a hidden (deprecated) one is not."""
    text = cli_markdown()
    sections = dict(re.findall(r"^## aes-swarm (\S+)\n(.*?)(?=^## |\Z)", text, re.M | re.S))
    for name, sub in subcommands(build_parser()).items():
        table = sections[name].split("```")[-1]
        shown = set(re.findall(r"^\| `(-[-\w]+)", table, re.M))
        visible = {a.option_strings[0] for a in visible_actions(sub) if a.option_strings}
        assert shown == visible, name
        hidden = {s for a in sub._actions if a.help == argparse.SUPPRESS for s in a.option_strings}
        assert not hidden & set(re.findall(r"`(-[-\w]+)", table)), name


def test_interface_md_and_tests_readme_are_current() -> None:
    """Builds every node with discovery off (no other process sees it), reads the test
    files' imports, and compares with docs/interface.md and tests/README.md."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "make_reference.py"), "--check"],
        capture_output=True, text=True, timeout=120, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    text = (ROOT / "docs" / "interface.md").read_text()
    for name in (interface.ENABLED, interface.SIM_STATS, interface.RECORDER_PROGRESS):
        assert f"`{name}`" in text
    assert "`desired_direction`" in text and "`robot_ids`" in text
