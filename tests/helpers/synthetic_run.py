"""A run of known samples streamed into a RunWriter, for tests/unit/test_run_writer.py
(also run as a script: ``python tests/helpers/synthetic_run.py OUT [--robots N]
[--flush-every S] [--file-size-limit BYTES]``).

Sample k of :func:`samples` is a formula of k, so a test can compare what reads back
with what was fed without keeping it. As a script it writes ``OUT/scenario.yaml``,
then streams samples into ``aes_ros.run_writer.RunWriter`` (real clock), printing
``written K`` after every flush, until it is killed or, with ``--file-size-limit``
(RLIMIT_FSIZE, a stand-in for a full disk), until a write fails: then it prints
``error …`` and exits 0.
"""

from __future__ import annotations

import argparse
import resource
import signal
import sys
import time
from pathlib import Path

import numpy as np

from aes_ros import scenario
from aes_ros.run_writer import RunWriter

#: Sim seconds between samples, and the drift of the swarm [m/s].
DT = 0.02
VELOCITY = np.array([-0.05, 0.02])
LABEL = "synthetic"


def synthetic_scenario(robots: int) -> scenario.Scenario:
    return scenario.load("combined").with_robots(robots)


def samples(
    start: int, stop: int, nominal: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples ``start`` … ``stop`` - 1 of the run: times (k,) [s], positions (k, N, 2)
    [m] (the formation drifting and turning slowly), headings (k, N) [rad]."""
    k = np.arange(start, stop)
    t = k * DT
    angle = 0.01 * t
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    x, y = nominal[:, 0], nominal[:, 1]
    positions = np.stack([c * x - s * y, s * x + c * y], axis=-1) + (t[:, None] * VELOCITY)[:, None]
    headings = np.angle(np.exp(1j * (angle[:, None] + 0.1 * np.sin(0.3 * t[:, None] + x))))
    return t, positions, headings


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--robots", type=int, default=9)
    parser.add_argument("--flush-every", type=float, default=0.05)
    parser.add_argument("--file-size-limit", type=int, default=0)
    args = parser.parse_args()
    from aes_ros.ros.launch.param_files import write_scenario

    sc = synthetic_scenario(args.robots)
    args.out.mkdir(parents=True, exist_ok=True)
    write_scenario(sc, args.out / "scenario.yaml")
    if args.file_size_limit:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (args.file_size_limit, args.file_size_limit))
    writer = RunWriter(args.out, sc, LABEL, flush_every=args.flush_every)
    nominal = sc.nominal_positions()
    reported, k = 0, 0
    while True:
        times, positions, headings = samples(k, k + 10, nominal)
        for i in range(len(times)):
            writer.add(times[i], positions[i], headings[i])
        k += len(times)
        if writer.error is not None:
            print(f"error {writer.error}", flush=True)
            print(f"written {writer.written}", flush=True)
            writer.finish()
            sys.exit(0)
        if writer.written != reported:
            reported = writer.written
            print(f"written {reported}", flush=True)
        time.sleep(0.002)


if __name__ == "__main__":
    main()
