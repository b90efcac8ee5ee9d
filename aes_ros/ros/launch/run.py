"""One launch from start to end (:func:`launch`) and what it produced (:class:`LaunchResult`).

Example::

    from aes_ros import scenario
    from aes_ros.ros.launch import LaunchConfig, launch
    result = launch(LaunchConfig(scenario.load("linear").with_robots(16), duration=20.0,
                                 lockstep=True, real_time_factor=0.0, out_dir=Path("out")))
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from aes_ros.ros.launch.config import LaunchConfig
from aes_ros.ros.launch.events import Event, fault_summary
from aes_ros.ros.launch.launcher import Launcher
from aes_ros.ros.programs import LaunchError


@dataclass
class LaunchResult:
    """What a run produced.

    samples : pose samples taken from ``t_go`` on; t_last : sim time [s] of the last.
    The samples themselves are in ``out_dir`` (:func:`aes_ros.trajectory.load_trajectory`):
    a run of hours is not held in memory.
    t_go : sim time [s] of the first sample (the last one before every robot moved).
    stopped_by : None when the run lasted ``duration``, else the signal's name.
    summary : the run's one-line summary ("" when nothing was written).
    killed : processes that had to be SIGKILLed at the end.
    exit_codes : every process's exit code (0 = clean shutdown).
    failure : why the run did not complete, or its outputs are incomplete (None: it
        completed, faults recovered on the way included).
    events : every fault and recovery (``events.csv``).
    """

    samples: int
    t_last: float
    t_go: float
    wall_time: float
    stopped_by: str | None = None
    summary: str = ""
    killed: list[str] = field(default_factory=list)
    exit_codes: dict[str, int] = field(default_factory=dict)
    failure: str | None = None
    events: list[Event] = field(default_factory=list)


def launch(config: LaunchConfig, say: Callable[[str], None] = print) -> LaunchResult:
    """Start, wait until every robot moves, run ``duration`` s of sim time, stop, write outputs.

    Raises LaunchError when the system does not start (nothing is written then).
    Once it runs, a fault it cannot recover from ends the run early instead: the
    outputs are written from what was sampled and :attr:`LaunchResult.failure`
    says why. Every process is stopped in any case.
    """
    launcher = Launcher(config, say)
    ok = False
    with launcher.signals_stop():
        try:
            launcher.start()
            launcher.wait_until_moving()
            try:
                launcher.run()
            except LaunchError as exc:  # a fault the run cannot get over
                launcher.failure = str(exc)
                say(f"launch: the run cannot go on: {exc}")
            ok = True
        finally:
            if launcher.writer is not None:  # the plots are drawn while the processes stop
                launcher.writer.start_drawing(launcher.work_dir / "scenario.yaml")
            killed = launcher.stop()
            if killed:
                say(f"launch: had to SIGKILL {', '.join(killed)}")
            launcher.cleanup(ok and launcher.failure is None and not killed)
    mon = launcher.monitor
    t_last = min(mon.times[-1], launcher._t_end) if mon is not None and mon.times else 0.0
    samples = max(0, mon.count - launcher.go_index) if mon is not None else 0
    events = launcher.events.events if launcher.events is not None else []
    result = LaunchResult(
        samples, t_last, float(launcher.t_go or 0.0), launcher.wall_time,
        stopped_by=launcher.stop_reason, killed=killed, exit_codes=launcher.exit_codes,
        failure=launcher.failure, events=events,
    )  # fmt: skip
    if launcher.stop_reason is not None:
        say(f"launch: stopped by {launcher.stop_reason} at sim time {t_last:.2f} s")
    if launcher.writer is not None:
        # drawn in a child: the launcher's memory stays what it was during the run
        result.summary = launcher.writer.finish(launcher.work_dir / "scenario.yaml")
        if launcher.writer.error is not None and result.failure is None:
            result.failure = f"the outputs are incomplete: {launcher.writer.error}"
    if launcher.supervision is not None:
        say(f"launch: {fault_summary(events, launcher.supervision.given_up)}")
    if launcher.events is not None:
        launcher.events.close()
    return result
