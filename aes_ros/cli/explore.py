"""``aes-swarm explore``: the studies built on sweeps, each regenerating its figures.

Examples::

    aes-swarm explore pareto                  # out/explore/pareto/pareto.png, …
    aes-swarm explore noise --workers 2
    aes-swarm explore robustness --scheduler tls://10.0.0.5:8786 \\
        --tls-ca ca.pem --tls-cert client.pem --tls-key client-key.pem
    aes-swarm explore perception --out docs/explore/perception   # the published figures
    aes-swarm explore ladder                  # out/explore/ladder/…
    aes-swarm explore clutter --runs 5        # out/explore/clutter/…

- ``pareto``: the Pareto front of (F̄/N, ψ̄) over (α, β, k) and where the paper's,
  the untuned and the TCACS gains lie on it (:mod:`aes_ros.studies.pareto`);
- ``noise``: the noise phase diagram over (D_r, D_θ) and the swarm size
  (:mod:`aes_ros.studies.noise`);
- ``robustness``: J and ψ̄ of the paper's and the TCACS gains under noise, size and
  failing robots (:mod:`aes_ros.studies.robustness`);
- ``perception``: how much position noise, delay, camera rate and missed detection
  the swarm tolerates before ψ̄ falls below 0.8 (:mod:`aes_ros.studies.perception`);
- ``ladder``: the reality-gap ladder, offline → offline with the tracker's error →
  pybullet kinematic → dynamic → dynamic in real time → with camera and tracker
  (:mod:`aes_ros.studies.ladder`; its 72 ROS runs start ``aes-swarm launch``, one at
  a time, and take about 40 minutes);
- ``clutter``: ψ̄, collisions per robot-minute and progress of the ``cluttered`` sheet
  against the number of posts across its path and the avoidance weight ``w_o``
  (:mod:`aes_ros.studies.clutter`; ``--runs`` and ``--seed`` apply to it).

The sweeps' tables go to ``--work`` (resumable: an interrupted study goes on where
it stopped), the figures, CSV and JSON to ``--out`` (default ``out/explore/STUDY``; the
published ones with ``--out docs/explore/STUDY``). Unlike ``launch`` or ``simulate``,
an earlier study's ``--out`` is replaced without ``--overwrite``: its figures are
regenerated whole from the tables, and the runs themselves, in ``--work``, are resumed,
not lost.
"""

from __future__ import annotations

import argparse
import importlib
import json
from pathlib import Path

from aes_ros.cli.options import MAX_RUNS, SEED_RULE, number_type, seed_type
from aes_ros.cli.sweep import add_scheduler_options, scheduler_from_args

STUDIES = ("pareto", "noise", "robustness", "perception", "ladder", "clutter")
#: The studies that take ``--runs`` and ``--seed``.
SEEDED = ("clutter",)
#: Where a study writes without ``--out``: never into the repository's docs/.
DEFAULT_OUT = Path("out/explore")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("study", choices=STUDIES, help="which study")
    p.add_argument(
        "--out", type=Path, default=None, metavar="DIR",
        help="the directory this command writes: figures and tables (default "
        "out/explore/STUDY, or STUDY_quick; the published ones: --out docs/explore/STUDY)",
    )  # fmt: skip
    p.add_argument(
        "--work", type=Path, default=Path("out/explore"),
        help="the sweeps' tables, kept to resume (default out/explore)",
    )  # fmt: skip
    add_scheduler_options(p)
    p.add_argument(
        "--workers", type=number_type(int, 1), default=None, metavar="K",
        help="a local Dask cluster of K workers",
    )  # fmt: skip
    p.add_argument(
        "--quick", action="store_true", help="a small version (fewer points, runs, robots)"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--runs", type=number_type(int, 1, MAX_RUNS), default=None, metavar="N",
        help="Monte-Carlo runs per point (clutter only; default: the study's own)",
    )  # fmt: skip
    p.add_argument(
        "--seed", type=seed_type, default=None, metavar="S",
        help=f"{SEED_RULE} (clutter only; default 0)",
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from aes_ros.params import ParameterError
    from aes_ros.studies.common import Where
    from aes_ros.sweep.spec import SweepSpecError

    if args.scheduler is not None and args.workers is not None:
        raise SweepSpecError("--scheduler and --workers: give one of them")
    seeded = {k: v for k in ("runs", "seed") if (v := getattr(args, k, None)) is not None}
    if seeded and args.study not in SEEDED:
        given = "/".join(f"--{k}" for k in seeded)
        raise ParameterError(f"{given}: only for explore {', '.join(SEEDED)}, not {args.study}")
    name = f"{args.study}_quick" if args.quick else args.study
    out = args.out if args.out is not None else DEFAULT_OUT / name
    work = args.work / name
    cluster = scheduler_from_args(args)
    where = Where(work, cluster, args.workers, progress=not args.no_progress)
    study = importlib.import_module(f"aes_ros.studies.{args.study}")
    result = study.run(out, where, quick=args.quick, **seeded)
    print(json.dumps(result, indent=1)[:2000])
    print(f"explore {args.study}: figures and tables in {out}")
    return 0
