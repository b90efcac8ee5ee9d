"""``aes-swarm simulate`` and ``params`` as a user runs them: outputs, and clear errors;
bad arguments of ``launch`` and ``steer`` rejected before anything starts.

``aes-swarm`` runs in-process (:func:`aes_ros.cli.main` returns the exit code, 2 on bad
input, argparse's errors included).
"""

from __future__ import annotations

import csv
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

import aes_ros.cli.dashboard
import aes_ros.ros.launch
import aes_ros.ros.steering
from aes_ros import scenario
from aes_ros.cli import main
from aes_ros.params import PARAMS
from aes_ros.trajectory import load_trajectory


class Run(NamedTuple):
    returncode: int
    stdout: str
    stderr: str


@pytest.fixture
def aes_swarm(capsys: pytest.CaptureFixture[str]) -> Callable[..., Run]:
    """``aes-swarm ARGS…`` in this process: (exit code, stdout, stderr)."""

    def run(*args: str) -> Run:
        code = main(list(args))
        out = capsys.readouterr()
        return Run(code, out.out, out.err)

    return run


def test_simulate_writes_every_output(tmp_path: Path, aes_swarm) -> None:
    out = tmp_path / "run"
    proc = aes_swarm(
        "simulate", "--setup", "linear", "--set", "rows=4", "--set", "cols=4",
        "--duration", "5", "--runs", "2", "--seed", "3", "--out", str(out),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = proc.stdout.strip().splitlines()[-1]
    assert summary.startswith("linear: N=16 runs=2")
    with open(out / "metrics.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == [
        "t", "alignment", "heading_order", "total_force", "centroid_x", "centroid_y",
        "angular_velocity", "contacts_per_s", "min_centre_distance",
    ]  # fmt: skip
    assert len(rows) == 101 and float(rows[-1]["t"]) == pytest.approx(5.0)
    assert float(rows[-1]["centroid_x"]) < float(rows[0]["centroid_x"])  # moving west
    traj = load_trajectory(out / "trajectory.h5")
    assert traj.times.shape == (101,)
    assert traj.positions.shape == (2, 101, 16, 2)
    assert traj.headings.shape == (2, 101, 16)
    for png in ("snapshots.png", "metrics.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_scenario_file_and_overrides_are_applied(tmp_path: Path, aes_swarm) -> None:
    text = Path(scenario.__file__).with_name("scenarios") / "linear.yaml"
    custom = tmp_path / "north.yaml"
    custom.write_text(text.read_text().replace("direction: [-1.0, 0.0]", "direction: [0.0, 1.0]"))
    out = tmp_path / "north"
    proc = aes_swarm(
        "simulate", "--scenario", str(custom), "--set", "rows=3", "--set", "cols=3",
        "--duration", "10", "--out", str(out),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    c = np.loadtxt(out / "metrics.csv", delimiter=",", skiprows=1, usecols=(4, 5))
    assert c[-1, 1] - c[0, 1] > 0.5  # moved north
    assert abs(c[-1, 0] - c[0, 0]) < 0.2


@pytest.mark.parametrize(
    ("args", "field", "allowed"),
    [
        (["--setup", "spiral"], "--setup", "linear, rotation, combined"),
        (["--set", "spacing=-0.2"], "spacing", "[0.01, 100]"),
        (["--set", "alpha=fast"], "alpha", "a number"),
        (["--set", "colour=red"], "colour", "allowed:"),
        (["--set", "alpha"], "--set", "name=value"),
        (["--dt", "5"], "dt", "[0.0001, 1]"),
    ],
)
def test_bad_input_exits_2_naming_the_field(
    tmp_path: Path, aes_swarm, args: list[str], field: str, allowed: str
) -> None:
    proc = aes_swarm("simulate", *args, "--out", str(tmp_path / "x"))
    assert proc.returncode == 2
    assert field in proc.stderr and allowed in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("alpha: [1, 2\n", "not valid YAML"),
        ("speed_of_light: 3\n", "unknown parameter 'speed_of_light'"),
        ("rows: 2.5\n", "rows"),
        ("- alpha\n", "expected a mapping"),
    ],
)
def test_bad_scenario_file_exits_2(tmp_path: Path, aes_swarm, content: str, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    proc = aes_swarm("simulate", "--scenario", str(path), "--out", str(tmp_path / "x"))
    assert proc.returncode == 2
    assert message in proc.stderr and "bad.yaml" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


def test_params_lists_every_parameter_with_its_range(aes_swarm) -> None:
    proc = aes_swarm("params")
    assert proc.returncode == 0
    for spec in PARAMS.values():
        assert f"`{spec.name}`" in proc.stdout
    assert "[0, 10]" in proc.stdout  # alpha's range


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["launch", "--layout", "ring"], "--layout"),
        (["launch", "--robots", "0"], "--robots"),
        (["launch", "--neighbor-source", "wifi"], "--neighbor-source"),
        (["launch", "--real-time-factor", "-1"], "--real-time-factor"),
        (["launch", "--set", "alpha=-1"], "alpha"),
        (["launch", "--setup", "spiral"], "--setup"),
        (["steer"], "--direction"),
        (["steer", "--omega", "nan"], "--omega"),
        (["launch", "--dashboard", "70000"], "--dashboard"),
        (["launch", "--discovery", "multicast"], "--discovery"),
        (["launch", "--discovery-server", "nowhere"], "--discovery-server"),
        (["launch", "--discovery-port", "70000"], "--discovery-port"),
        (["launch", "--discovery", "simple", "--discovery-port", "11811"], "discovery_port"),
        (["dashboard", "--port", "-1"], "--port"),
        (["dashboard", "--robots", "0"], "--robots"),
    ],
)
def test_bad_arguments_exit_2_naming_the_option(
    monkeypatch: pytest.MonkeyPatch, aes_swarm, args: list[str], option: str
) -> None:
    """``launch``, ``steer`` and ``dashboard`` reject bad arguments before they start anything."""

    def must_not_run(*_args, **_kwargs):
        raise AssertionError(f"aes-swarm {args[0]} went on with bad arguments")

    monkeypatch.setattr(aes_ros.ros.launch, "launch", must_not_run)
    monkeypatch.setattr(aes_ros.ros.steering, "steer", must_not_run)
    monkeypatch.setattr(aes_ros.cli.dashboard, "serve", must_not_run)
    out = aes_swarm(*args)
    assert out.returncode == 2, out
    assert option in out.stderr


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--param", "gamma=0:1:3"], "gamma"),
        (["--param", "alpha=0.3:0.1:3"], "alpha: the range 0.3:0.1 is empty"),
        (["--param", "k=0:500:3"], "k: 500 is out of range; allowed [0, 100]"),
        (["--param", "alpha=0:1"], "alpha: a grid needs a count"),
        (["--param", "alpha=0:1:3", "--transient", "99"], "--transient 99"),
        (["--param", "alpha=0:1:3", "--workers", "2", "--scheduler", "tcp://x:1"], "--scheduler"),
        (["--param", "alpha=0:1:3", "--fail", "2@5"], "--fail 2@5: need a fraction in [0, 1]"),
        (["--param", "alpha=0:1:3", "--fail", "10%"], "--fail '10%': need FRACTION@TIME"),
    ],
)
def test_bad_sweep_specs_exit_2_naming_the_field(
    tmp_path: Path, aes_swarm, args: list[str], field: str
) -> None:
    out = aes_swarm("sweep", "--setup", "linear", "--duration", "5", "--out", str(tmp_path), *args)
    assert out.returncode == 2, out
    assert field in out.stderr
    assert not (tmp_path / "runs.csv").exists()


def test_sweep_writes_its_table_and_resumes(tmp_path: Path, aes_swarm) -> None:
    args = ["sweep", "--setup", "linear", "--robots", "9", "--duration", "2", "--runs", "2",
            "--param", "beta=0.5,1", "--no-progress", "--out", str(tmp_path)]  # fmt: skip
    first = aes_swarm(*args)
    assert first.returncode == 0, first
    with open(tmp_path / "runs.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["point"], r["run"], r["beta"]) for r in rows] == [
        ("0", "0", "0.5"), ("0", "1", "0.5"), ("1", "0", "1.0"), ("1", "1", "1.0")
    ]  # fmt: skip
    again = aes_swarm(*args)
    assert "2 done before, 0 tasks" in again.stdout


@pytest.mark.parametrize("command", ["steer", "launch", "params"])
def test_a_command_loads_only_what_it_needs(command: str) -> None:
    """``aes-swarm steer`` and ``launch`` do not load the offline simulator, the optimiser
    or matplotlib that other commands need: loading every command's module took 1.5 s
    before any of them ran."""
    probe = (
        "import sys\n"
        "from aes_ros.cli import main\n"
        "try:\n"
        f"    main([{command!r}, '--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = ('aes_ros.simulator', 'aes_ros.optim.tcacs', 'scipy.optimize', 'matplotlib')\n"
        "print(*sorted(m for m in heavy if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert f"usage: aes-swarm {command}" in done.stdout
    assert done.stdout.splitlines()[-1] == ""
