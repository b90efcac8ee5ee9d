"""One flag name per idea across ``aes-swarm`` and the bench scripts (``aes_ros.cli.options``):
``--runs``, ``--arena-layout``, ``--camera-size``, ``--duration``, ``--out``, ``--seed``; the
old spellings still parse to the same value, with a warning, hidden from ``--help``."""

from __future__ import annotations

import argparse
import importlib.util
import re
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

from aes_ros.cli import build_parser, main
from aes_ros.cli.options import SEED_RULE

REPO = Path(__file__).resolve().parents[2]
BENCH = REPO / "bench"
#: Scripts with a command line of their own (naive_swarm.py is started by a benchmark;
#: modules without a parser are their helpers).
SCRIPTS = sorted(
    p
    for p in BENCH.glob("*.py")
    if p.name != "naive_swarm.py" and "argparse.ArgumentParser(" in p.read_text()
)
#: Old spellings of an idea that has one name now.
OLD = {"--mc", "--eval-runs", "--repeat", "--repeats", "--seconds", "--closed-loop-seconds"}


def subcommands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def load(script: Path) -> ModuleType:
    sys.path.insert(0, str(BENCH))  # the scripts import their siblings
    try:
        name = f"_vocabulary_{script.stem}"
        spec = importlib.util.spec_from_file_location(name, script)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up there
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCH))
    return module


class Parsed(Exception):  # noqa: N818 (not an error: how the test stops main())
    """Raised with the namespace of a bench script's command line, before it runs."""

    def __init__(self, args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
        self.namespace, self.parser = args, parser


def bench_parser(monkeypatch: pytest.MonkeyPatch, script: Path) -> Callable[[list[str]], Parsed]:
    """The command line of ``script`` as a function argv -> :class:`Parsed` (its main()
    stops right after parsing)."""
    module = load(script)
    original = argparse.ArgumentParser.parse_args

    def stop(self, args=None, namespace=None):
        raise Parsed(original(self, args, namespace), self)

    def parse(argv: list[str]) -> Parsed:
        with monkeypatch.context() as m:
            m.setattr(argparse.ArgumentParser, "parse_args", stop)
            m.setattr(sys, "argv", [script.name, *argv])
            with pytest.raises(Parsed) as got:
                module.main()
        return got.value

    return parse


def visible_flags(parser: argparse.ArgumentParser) -> set[str]:
    return {
        flag
        for action in parser._actions
        if action.help is not argparse.SUPPRESS
        for flag in action.option_strings
    }


@pytest.mark.parametrize("name", sorted(subcommands()))
def test_every_subcommand_uses_the_vocabulary(name: str) -> None:
    parser = subcommands()[name]
    flags = visible_flags(parser)
    assert not flags & OLD, name
    assert "--camera" not in flags, name  # an image size is --camera-size
    if name == "calibrate":
        assert "--arena-layout" in flags and "--layout" not in flags
    text = parser.format_help()
    for old in (*OLD, "--camera", "--layout" if name == "calibrate" else "--mc"):
        assert not re.search(rf"{old}\b(?!-)", text), (name, old)
    if "--seed" in flags:  # the one seed rule, said where the seed is given
        assert " ".join(SEED_RULE.split()) in " ".join(text.split()), name


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_every_bench_script_uses_the_vocabulary(
    script: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    parser = bench_parser(monkeypatch, script)([]).parser
    flags = visible_flags(parser)
    assert not flags & OLD, script.name
    assert "--camera" not in flags, script.name
    out = next((a for a in parser._actions if "--out" in a.option_strings), None)
    if out is not None:  # an option, never into the repository's docs/ unless asked
        assert out.default is None or Path(out.default).parts[0] == "out", script.name


@pytest.mark.parametrize(
    ("command", "old", "new", "value", "dest"),
    [
        (["optimize"], "--mc", "--runs", "3", "runs"),
        (["study"], "--mc", "--runs", "3", "runs"),
        (["study"], "--eval-runs", "--held-out", "7", "held_out"),
        (["sweep", "--param", "k=1,2"], "--mc", "--runs", "4", "runs"),
        (["calibrate", "--image", "f.png", "--camera-info", "c.yaml"], "--layout",
         "--arena-layout", "a.yaml", "arena_layout"),
        (["launch"], "--camera", "--camera-size", "640x480", "camera_size"),
    ],
)  # fmt: skip
def test_an_old_spelling_still_works_with_a_warning(
    command: list[str], old: str, new: str, value: str, dest: str, capsys
) -> None:
    tail = [] if command[0] == "launch" else ["--out", "o"]
    expected = getattr(build_parser().parse_args([*command, new, value, *tail]), dest)
    assert capsys.readouterr().err == ""
    assert getattr(build_parser().parse_args([*command, old, value, *tail]), dest) == expected
    assert capsys.readouterr().err == f"aes-swarm {command[0]}: {old} is deprecated; use {new}\n"
    assert not re.search(rf"{old}\b(?!-)", subcommands()[command[0]].format_help())


@pytest.mark.parametrize(
    ("script", "old", "new", "dest"),
    [
        ("bench_sweep.py", "--mc", "--runs", "runs"),
        ("bench_sweep.py", "--repeats", "--trials", "trials"),
        ("bench_faults.py", "--repeats", "--runs", "runs"),
        ("bench_ros.py", "--repeat", "--runs", "runs"),
        ("compare_optimizers.py", "--mc", "--runs", "runs"),
        ("bench_dashboard.py", "--seconds", "--duration", "duration"),
        ("bench_floor.py", "--seconds", "--duration", "duration"),
        ("bench_tracking.py", "--seconds", "--duration", "duration"),
        ("bench_tracking.py", "--closed-loop-seconds", "--closed-loop-duration",
         "closed_loop_duration"),
    ],
)  # fmt: skip
def test_a_bench_scripts_old_spelling_still_works_with_a_warning(
    script: str, old: str, new: str, dest: str, monkeypatch, capsys
) -> None:
    parse = bench_parser(monkeypatch, BENCH / script)
    assert (
        getattr(parse([old, "5"]).namespace, dest)
        == getattr(parse([new, "5"]).namespace, dest)
        == 5
    )
    assert capsys.readouterr().err == f"{script}: {old} is deprecated; use {new}\n"


def test_camera_size_of_bench_tracking(monkeypatch, capsys) -> None:
    parse = bench_parser(monkeypatch, BENCH / "bench_tracking.py")
    assert parse(["--camera", "640x480"]).namespace.camera_size == [(640, 480)]
    assert "--camera is deprecated; use --camera-size" in capsys.readouterr().err


def test_duration_zero_is_until_ctrl_c_only_where_a_run_can_be_open_ended(
    monkeypatch, capsys
) -> None:
    assert build_parser().parse_args(["launch", "--duration", "0"]).duration == 0.0
    for argv in (["simulate", "--out", "o"], ["sweep", "--param", "k=1,2", "--out", "o"]):
        assert main([*argv, "--duration", "0"]) == 2
        err = capsys.readouterr().err
        assert "argument --duration: need > 0 (0 = until Ctrl-C only for launch)" in err
    for script in ("bench_sim.py", "bench_soak.py"):
        with pytest.raises(SystemExit):
            bench_parser(monkeypatch, BENCH / script)(["--duration", "0"])
        assert "--duration: need > 0" in capsys.readouterr().err


def test_explore_writes_under_out_unless_told(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys
) -> None:
    import aes_ros.studies.pareto as pareto

    monkeypatch.chdir(tmp_path)
    written: list[Path] = []
    monkeypatch.setattr(pareto, "run", lambda out, where, quick: written.append(out) or {})
    assert main(["explore", "pareto", "--no-progress"]) == 0
    assert main(["explore", "pareto", "--quick", "--no-progress"]) == 0
    assert main(["explore", "pareto", "--out", "docs/explore/pareto", "--no-progress"]) == 0
    assert written == [
        Path("out/explore/pareto"),
        Path("out/explore/pareto_quick"),
        Path("docs/explore/pareto"),
    ]
    assert "out/" in (REPO / ".gitignore").read_text().split()


def test_report_takes_out_and_still_the_old_positional(tmp_path: Path, capsys) -> None:
    assert main(["report", "--out", str(tmp_path)]) == 2
    new = capsys.readouterr().err
    assert new.startswith("aes-swarm report: error: --out: ") and "deprecated" not in new
    assert main(["report", str(tmp_path)]) == 2
    old = capsys.readouterr().err
    assert old == "aes-swarm report: DIR is deprecated; use --out DIR\n" + new
    assert main(["report"]) == 2
    assert "--out DIR is required" in capsys.readouterr().err


def test_calibrate_out_is_a_directory_and_a_file_still_works(tmp_path: Path, capsys) -> None:
    (tmp_path / "calibration.yaml").write_text("the lab's")
    given = ["calibrate", "--image", "f.png", "--arena-layout", "a.yaml", "--camera-info", "c"]
    assert main([*given, "--out", str(tmp_path)]) == 2  # DIR/calibration.yaml is there
    new = capsys.readouterr().err
    assert f"--out {tmp_path / 'calibration.yaml'} holds an earlier calibration" in new
    assert "deprecated" not in new
    assert main([*given, "--out", str(tmp_path / "calibration.yaml")]) == 2
    old = capsys.readouterr().err
    assert old.startswith("aes-swarm calibrate: --out FILE.yaml is deprecated; use --out DIR")
    assert old.endswith(new)


def test_params_ros_maps_the_supervisors_names(capsys) -> None:
    assert main(["params", "--ros"]) == 0
    table = capsys.readouterr().out
    assert "| `/supervisor` | `desired_direction` | `direction` |" in table
    assert "| `/supervisor` | `rotation_rate` | `omega` |" in table
    assert "| `/supervisor` | `enabled` | none (ROS only) |" in table


def test_steer_enable_and_disable_exclude_each_other(capsys) -> None:
    assert main(["steer", "--enable", "--disable"]) == 2
    assert "not allowed with argument --enable" in capsys.readouterr().err
