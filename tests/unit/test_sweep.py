"""Parameter sweeps (aes_ros.sweep): specs, points, batching with common random numbers,
resuming an interrupted sweep, and the outputs."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from aes_ros import scenario
from aes_ros.cli import main
from aes_ros.sweep import cluster, engine, runs
from aes_ros.sweep.engine import Sweep, execute
from aes_ros.sweep.spec import SweepSpecError, parse_axis, points


def test_grid_specs_linear_log_and_lists() -> None:
    assert parse_axis("alpha=0.1:0.3:3").grid() == pytest.approx([0.1, 0.2, 0.3])
    assert parse_axis("k=log:0.1:10:3").grid() == pytest.approx([0.1, 1.0, 10.0])
    assert parse_axis("robots=25,100,400").grid().tolist() == [25, 100, 400]
    assert parse_axis("rows=2:5:3").grid().tolist() == [2, 4, 5]  # integers rounded
    grid = points([parse_axis("alpha=0.1:0.2:2"), parse_axis("k=1,2,3")])
    assert grid.shape == (6, 2)
    assert grid[:3].tolist() == [[0.1, 1], [0.1, 2], [0.1, 3]]  # the first axis slowest


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("gamma=0:1:3", "gamma: not a parameter"),
        ("formation=0:1:2", "formation: not a parameter"),
        ("alpha=0.2:0.1:3", "empty"),
        ("alpha=0.1:0.2:0", "empty"),
        ("alpha=0.1:0.1:3", "one number"),
        ("alpha=-1:0.1:3", r"-1 is out of range; allowed \[0, 10\]"),
        ("robots=0,10", "out of range"),
        ("k=log:0:5:3", "log range needs low > 0"),
        ("beta=a:2:3", "'a' is not a number"),
        ("beta=0:2:x", "not an integer"),
        ("beta=nan:2:3", "not finite"),
        ("beta", "need name="),
        ("beta=1:2:3:4", "need low:high:n"),
    ],
)
def test_bad_specs_name_the_field(text: str, reason: str) -> None:
    with pytest.raises(SweepSpecError, match=reason):
        axis = parse_axis(text)
        axis.grid()


def test_a_grid_needs_counts_and_a_parameter_once() -> None:
    with pytest.raises(SweepSpecError, match="a grid needs a count"):
        points([parse_axis("alpha=0.1:0.2")])
    with pytest.raises(SweepSpecError, match="alpha: given more than once"):
        points([parse_axis("alpha=0.1:0.2:2"), parse_axis("alpha=1,2")])


def test_latin_hypercube_fills_every_stratum_of_every_axis() -> None:
    axes = [parse_axis("alpha=0:1"), parse_axis("k=log:0.01:100")]
    sample = points(axes, lhs=50, seed=3)
    assert sample.shape == (50, 2)
    strata_alpha = np.floor(sample[:, 0] * 50).astype(int)
    strata_k = np.floor((np.log10(sample[:, 1]) + 2) / 4 * 50).astype(int)
    assert sorted(strata_alpha) == list(range(50)) and sorted(strata_k) == list(range(50))
    assert np.array_equal(sample, points(axes, lhs=50, seed=3))  # the seed decides
    assert not np.array_equal(sample, points(axes, lhs=50, seed=4))


def _sweep(**kw) -> Sweep:
    base = scenario.load("linear").with_robots(9).with_overrides({"duration": 2.0})
    axes = [parse_axis("alpha=0.02:0.2:3"), parse_axis("d_r=0,1")]
    return Sweep(base, axes, points(axes), mc=kw.pop("mc", 3), **kw)


def test_a_points_runs_do_not_depend_on_its_batch() -> None:
    sweep = _sweep()
    together = runs.run_task(sweep.base, sweep.names, [0, 1, 2], sweep.points[:3], [5, 6], 0.0)
    alone = runs.run_task(sweep.base, sweep.names, [1], sweep.points[1:2], [5, 6], 0.0)
    assert [r for r in together if r["point"] == 1] == alone
    # common random numbers: every point sees the same seeds, so its runs differ only
    # by its parameters; with other seeds the numbers change
    assert [r["seed"] for r in together] == [5, 6] * 3
    other = runs.run_task(sweep.base, sweep.names, [1], sweep.points[1:2], [7, 8], 0.0)
    assert other[0]["psi"] != alone[0]["psi"]


def test_points_that_change_the_sheet_get_tasks_of_their_own() -> None:
    axes = [parse_axis("robots=4,9"), parse_axis("alpha=0.1,0.2,0.3")]
    grid = points(axes)
    tasks = runs.make_tasks(["robots", "alpha"], grid, skip={4}, points_per_task=2)
    assert [t.indices for t in tasks] == [(0, 1), (2,), (3, 5)]


def _read(path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_outputs_and_resuming_an_interrupted_sweep(tmp_path, monkeypatch) -> None:
    full = tmp_path / "full"
    execute(_sweep(), full, points_per_task=2, progress=False, say=lambda _: None)
    rows = _read(full / "runs.csv")
    assert len(rows) == 6 * 3 and [int(r["point"]) for r in rows[:4]] == [0, 0, 0, 1]
    summary = _read(full / "points.csv")
    assert len(summary) == 6 and all(r["runs"] == "3" for r in summary)
    psi = [float(r["psi"]) for r in rows if r["point"] == "0"]
    assert float(summary[0]["psi_mean"]) == pytest.approx(np.mean(psi))
    assert (full / "sweep_metrics.png").stat().st_size > 10_000

    # interrupted after its first task: the finished points stay on disk
    cut = tmp_path / "cut"
    calls = []
    real = runs.run_task

    def fails_second(*args, **kwargs):
        calls.append(args[2])
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "run_task", fails_second)
    with pytest.raises(KeyboardInterrupt):
        execute(_sweep(), cut, points_per_task=2, progress=False, say=lambda _: None)
    assert {r["point"] for r in _read(cut / "runs.csv")} == {"0", "1"}
    # the same sweep again: only the rest is simulated, and the outputs equal the full run
    calls.clear()
    monkeypatch.setattr(engine, "run_task", lambda *a, **k: calls.append(a[2]) or real(*a, **k))
    execute(_sweep(), cut, points_per_task=2, progress=False, say=lambda _: None)
    assert calls == [(2, 3), (4, 5)]
    for name in ("runs.csv", "points.csv"):
        assert (cut / name).read_text() == (full / name).read_text()


def test_another_sweep_into_the_same_directory_is_refused(tmp_path) -> None:
    execute(_sweep(), tmp_path, progress=False, say=lambda _: None)
    with pytest.raises(SweepSpecError, match=r"holds another sweep.*mc"):
        execute(_sweep(mc=2), tmp_path, progress=False, say=lambda _: None)


def test_a_sweep_written_before_a_parameter_existed_resumes_unless_it_is_changed(
    tmp_path,
) -> None:
    """A sweep.json from before a parameter was added (e.g. the perception_* ones) ran
    it at its default: the same sweep resumes there; one that sets it is refused."""
    import json

    execute(_sweep(), tmp_path, progress=False, say=lambda _: None)
    spec = tmp_path / engine.SPEC_FILE
    old = json.loads(spec.read_text())
    del old["scenario"]["perception_sigma"]
    spec.write_text(json.dumps(old))
    execute(_sweep(), tmp_path, progress=False, say=lambda _: None)  # resumes: all done
    changed = _sweep()
    changed.base = changed.base.with_overrides({"perception_sigma": 0.01})  # a dataclass
    with pytest.raises(SweepSpecError, match=r"holds another sweep.*scenario"):
        execute(changed, tmp_path, progress=False, say=lambda _: None)


@pytest.fixture
def pems(tmp_path):
    """Three files where the --tls-* options point (their contents are not read here)."""
    files = [tmp_path / name for name in ("ca.pem", "client.pem", "client-key.pem")]
    for path in files:
        path.write_text("PEM\n")
    return files


def test_a_tls_scheduler_gets_the_users_certificates_and_requires_encryption(pems) -> None:
    target = cluster.scheduler("tls://10.0.0.5:8786", *pems, warn=pytest.fail)
    security = target.security()
    assert security.require_encryption
    assert (security.tls_ca_file, security.tls_client_cert, security.tls_client_key) == tuple(
        map(str, pems)
    )
    assert cluster.scheduler("tcp://127.0.0.1:8786", warn=pytest.fail).security() is None


@pytest.mark.parametrize(
    ("address", "files", "reason"),
    [
        ("tls://10.0.0.5:8786", "", "tls:// needs --tls-ca, --tls-cert, --tls-key"),
        ("tls://10.0.0.5:8786", "ca", "--tls-cert, --tls-key: TLS needs all three"),
        ("tls://10.0.0.5:8786", "ca cert", "--tls-key: TLS needs all three"),
        ("tls://10.0.0.5:8786", "ca cert nokey", "--tls-key .*missing.pem: no such file"),
        ("tcp://10.0.0.5:8786", "ca cert key", "the --tls-\\* files need a tls:// address"),
        ("ucx://10.0.0.5:8786", "", "need tcp://HOST:PORT or tls://HOST:PORT"),
        ("tls://10.0.0.5", "ca cert key", "need tcp://HOST:PORT or tls://HOST:PORT"),
        ("tcp://10.0.0.5:port", "", "need tcp://HOST:PORT or tls://HOST:PORT"),
    ],
)
def test_bad_scheduler_options_name_the_option(pems, tmp_path, address, files, reason) -> None:
    paths = {"ca": pems[0], "cert": pems[1], "key": pems[2], "nokey": tmp_path / "missing.pem"}
    given = [paths[name] for name in files.split()]
    args = [*given, *[None] * (3 - len(given))]
    with pytest.raises(SweepSpecError, match=reason):
        cluster.scheduler(address, *args, warn=pytest.fail)


@pytest.mark.parametrize(
    ("address", "warned"),
    [
        ("tcp://10.0.0.5:8786", True),
        ("head:8786", True),
        ("tcp://[::1]:8786", False),
        ("tcp://127.0.0.1:8786", False),
        ("localhost:8786", False),
    ],
)
def test_plain_tcp_to_another_host_warns_that_reaching_it_runs_code(address, warned) -> None:
    said: list[str] = []
    assert cluster.scheduler(address, warn=said.append).address == address
    assert bool(said) == warned
    if warned:
        assert "anyone who reaches it runs code" in said[0] and "tls://" in said[0]


def test_the_cli_refuses_tls_options_with_exit_2_before_any_work(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    base = ["sweep", "--param", "alpha=0.1:0.2:2", "--out", str(out), "--no-progress"]
    assert main([*base, "--scheduler", "tls://127.0.0.1:1"]) == 2
    assert "tls:// needs --tls-ca, --tls-cert, --tls-key" in capsys.readouterr().err
    assert main([*base, "--tls-ca", str(tmp_path / "ca.pem")]) == 2
    assert "need --scheduler tls://HOST:PORT" in capsys.readouterr().err
    assert not out.exists()
