"""Outputs are never lost by accident: a command refuses to write over an earlier run.

A command that writes a run's files into a place the user names (``aes-swarm launch
--out`` and ``--record``, ``simulate --out``, ``optimize --out``, ``calibrate --out``)
first looks for the files it would write. If one of them is there (an earlier run's),
it stops before it starts anything, with exit code 2 and a message naming the place and
the files, unless ``--overwrite`` is given: then the earlier run's files of those names
are removed first, and nothing else in the directory is touched. A new or empty
directory, or one holding only other files, is written into as it is. A directory that
belongs to another user (not root) is refused whatever it holds (:func:`refuse_foreign`): its
owner could put a link where a run's file is about to be created (in ``/tmp``, say).

Example::

    found = check_out_dir(Path("out/run"), LAUNCH_OUTPUTS, overwrite=args.overwrite)
    remove(found)  # only reached with --overwrite
"""

from __future__ import annotations

import argparse
import os
import shutil
from collections.abc import Iterable
from pathlib import Path

from aes_ros.params import ParameterError

#: The option that lets a command replace an earlier run (one word for every command).
OVERWRITE = "--overwrite"

#: What ``aes-swarm launch`` writes into ``--out`` (:mod:`aes_ros.ros.launch`).
LAUNCH_OUTPUTS = (
    "run.json", "trajectory.h5", "metrics.csv", "snapshots.png", "metrics.png", "events.csv",
    "scenario.yaml", "robots.yaml", "arena.yaml", "ros_env.sh", "logs",
)  # fmt: skip
#: What ``aes-swarm simulate`` writes into ``--out`` (:func:`aes_ros.report.write_run_outputs`).
SIMULATE_OUTPUTS = ("trajectory.h5", "metrics.csv", "snapshots.png", "metrics.png")
#: What ``aes-swarm optimize`` writes into ``--out``
#: (:func:`aes_ros.optim.tuning.write_tune_outputs`).
OPTIMIZE_OUTPUTS = ("result.json", "history.csv", "convergence.png")


class EarlierRunError(ParameterError):
    """An output of an earlier run is where this run would write (a ``ParameterError``:
    the CLI exits with code 2 and the message)."""


class ForeignDirectoryError(ParameterError):
    """The directory a run would write into belongs to another user."""


def refuse_foreign(directory: Path, option: str) -> None:
    """:class:`ForeignDirectoryError` if ``directory`` exists and belongs to neither this
    user nor root (not followed if it is a link: a link is judged by its own owner)."""
    try:
        owner = os.lstat(directory).st_uid
    except FileNotFoundError:
        return
    if owner not in (os.geteuid(), 0):
        raise ForeignDirectoryError(
            f"{option} {directory}: belongs to another user (uid {owner}), who could put a "
            "link where this run's files go; choose a directory of your own"
        )


def earlier_files(directory: Path, names: Iterable[str]) -> list[Path]:
    """The entries of ``names`` present in ``directory`` (a dangling symbolic link too)."""
    directory = Path(directory)
    return [directory / name for name in names if os.path.lexists(directory / name)]


def refuse(
    found: list[Path], where: str, overwrite: bool, what: str = "an earlier run"
) -> list[Path]:
    """:class:`EarlierRunError` naming ``where``, ``what`` it holds and ``found``, unless
    ``overwrite`` or nothing was found; returns ``found``."""
    if found and not overwrite:
        names = ", ".join(path.name for path in found[:6]) + (" …" if len(found) > 6 else "")
        raise EarlierRunError(
            f"{where} holds {what} ({names}); choose another place, or add "
            f"{OVERWRITE} to replace it"
        )
    return found


def check_out_dir(
    directory: Path | None, names: Iterable[str], *, overwrite: bool, option: str = "--out"
) -> list[Path]:
    """Refuse (:class:`EarlierRunError`) to write ``names`` into ``directory`` where one of
    them exists, unless ``overwrite``, and (:class:`ForeignDirectoryError`) a
    ``directory`` of another user's; returns the existing ones (to :func:`remove`).
    ``option`` names the directory in the message; None: nothing to check."""
    if directory is None:
        return []
    refuse_foreign(Path(directory), option)
    return refuse(earlier_files(directory, names), f"{option} {directory}", overwrite)


def remove(paths: Iterable[Path]) -> list[Path]:
    """Remove ``paths`` (files and symbolic links themselves, never what a link points
    to; directories with what they hold); returns what was removed."""
    removed = []
    for path in paths:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def add_overwrite_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--overwrite``: replace an earlier run's ``what`` instead of refusing."""
    parser.add_argument(
        OVERWRITE, action="store_true",
        help=f"replace an earlier run's {what} (its files are removed first); without it "
        "a command whose outputs are already there stops before it starts (exit code 2)",
    )  # fmt: skip
