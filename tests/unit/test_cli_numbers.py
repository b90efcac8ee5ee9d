"""Any number on the command line ends as exit code 2 and a message naming the field
and what is allowed, never a traceback: integers of hundreds of digits (beyond a
float), negative seeds, counts beyond memory, overflowing floats, for ``--set`` of every
kind of parameter and every number-typed option of the subcommands."""

from __future__ import annotations

from pathlib import Path

import pytest

import aes_ros.cli.dashboard
import aes_ros.ros.launch
from aes_ros.cli import main
from aes_ros.params import PARAMS

HUGE = "9" * 400  # an int beyond float's range (about 1.8e308)
LONGER = "9" * 5000  # beyond Python's int-from-text limit (4300 digits)


@pytest.mark.parametrize(
    ("assignment", "allowed"),
    [
        (f"alpha={HUGE}", PARAMS["alpha"].allowed()),
        (f"alpha=-{HUGE}", PARAMS["alpha"].allowed()),
        (f"rows={HUGE}", PARAMS["rows"].allowed()),
        (f"rows=-{HUGE}", PARAMS["rows"].allowed()),
        (f"rows={LONGER}", PARAMS["rows"].allowed()),
        ("rows=1e400", PARAMS["rows"].allowed()),
        ("dt=1e400", PARAMS["dt"].allowed()),
        (f"direction={HUGE},0", PARAMS["direction"].allowed()),
        (f"rotation_center=0,-{HUGE}", PARAMS["rotation_center"].allowed()),
        (f"arena=0,{HUGE},0,1", "four numbers"),
        (f"clip={HUGE}", "true or false"),
    ],
)
def test_set_with_any_number_exits_2_naming_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], assignment: str, allowed: str
) -> None:
    code = main(["simulate", "--set", assignment, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2, err
    field = assignment.partition("=")[0]
    assert f"{field}:" in err and allowed in err, err
    assert len(err) < 600, "the message quotes the value, not all 400 digits of it"
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("args", "option", "allowed"),
    [
        (["simulate", "--robots", HUGE], "--robots", "<= 1000000"),
        (["simulate", "--robots", "0"], "--robots", ">= 1"),
        (["simulate", "--seed", "-1"], "--seed", ">= 0"),
        (["simulate", "--seed", HUGE], "--seed", "<= 9223372036854775807"),
        (["simulate", "--runs", HUGE], "--runs", "<= 100000"),
        (["simulate", "--runs", LONGER], "--runs", "not an integer"),
        (["simulate", "--dt", HUGE], "dt", "[0.0001, 1]"),
        (["simulate", "--duration", "-" + HUGE], "--duration", "not finite"),
        (["simulate", "--duration", HUGE[:7]], "duration", "[0, 100000]"),
        (["optimize", "--evals", HUGE], "--evals", "<= 1000000000"),
        (["optimize", "--runs", HUGE], "--runs", "<= 100000"),
        (["optimize", "--seed", "-5"], "--seed", ">= 0"),
        (["study", "--evals", HUGE], "--evals", "<= 1000000000"),
        (["study", "--restarts", HUGE], "--restarts", "<= 100000"),
        (["dashboard", "--robots", HUGE], "--robots", "<= 1000000"),
        (["launch", "--robots", HUGE], "--robots", "<= 1000000"),
        (["launch", "--seed", "-1"], "--seed", ">= 0"),
        (["sweep", "--param", "alpha=0:1:3", "--seed", HUGE], "--seed", "<= 9223372036854775807"),
        (["sweep", "--param", "alpha=0:1", "--lhs", HUGE], "--lhs", "<= 1000000"),
        (["sweep", "--param", f"alpha=0:1:{HUGE}"], "--param alpha", "n <= 1000000"),
        (["sweep", "--param", "alpha=0:1:1000", "--param", "k=0.1:1:1001"], "--param", "1000000"),
    ],
)
def test_number_options_exit_2_naming_the_option_and_the_range(
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    option: str,
    allowed: str,
) -> None:
    def must_not_run(*_args: object, **_kwargs: object) -> None:
        raise AssertionError(f"aes-swarm {args[0]} went on with {args[1:]}")

    monkeypatch.setattr(aes_ros.ros.launch, "launch", must_not_run)
    monkeypatch.setattr(aes_ros.cli.dashboard, "serve", must_not_run)
    code = main([*args, "--out", str(tmp_path / "x")] if args[0] != "dashboard" else args)
    err = capsys.readouterr().err
    assert code == 2, err
    assert option in err and allowed in err, err
    assert "Traceback" not in err and len(err) < 2000
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("content", "field"),
    [
        (f"alpha: {HUGE}\n", "alpha"),
        (f"rows: {HUGE}\n", "rows"),
        ("direction: {x: 1, y: 0}\n", "direction"),
        ("arena: 5\n", "arena"),
        (f"rotation_center: [0, {HUGE}]\n", "rotation_center"),
    ],
)
def test_scenario_file_with_any_value_exits_2_naming_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, field: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    code = main(["simulate", "--scenario", str(path), "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "bad.yaml" in err and f"{field}:" in err and len(err) < 600, err
