"""The run's fault and recovery log: ``events.csv``, one line per event, on disk at once.

Columns: ``wall_time`` (ISO 8601, local time with offset), ``sim_time`` [s] (the
latest sim time the launcher saw; empty before the first poses), ``process``,
``event`` (what happened), ``exit`` (exit code, or the signal's name), ``action``
(what the launcher did about it). Every line is written with one ``os.write`` of
a whole line to a file opened for appending, so the file holds every event up to
a crash of the launcher itself and is never left with half a line.

Besides the launcher's own events (faults, restarts, recoveries), a process can
report one by logging a line with :data:`~aes_ros.ros.interface.LOG_EVENT`
(:class:`LogEvents`): the supervisor's arena keeper does when it turns or stops
the swarm.
"""

from __future__ import annotations

import csv
import io
import os
import signal
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Protocol

from aes_ros.ros import interface as names

COLUMNS = ("wall_time", "sim_time", "process", "event", "exit", "action")


def exit_text(returncode: int | None) -> str:
    """``0``/``1``/… for an exit code, ``SIGKILL`` for a death by signal, "" for none."""
    if returncode is None:
        return ""
    if returncode < 0:
        try:
            return signal.Signals(-returncode).name
        except ValueError:
            return f"signal {-returncode}"
    return str(returncode)


@dataclass(frozen=True)
class Event:
    process: str
    event: str
    exit: str = ""
    action: str = ""
    sim_time: float | None = None


class EventLog:
    """Appends events to ``path`` and says each one (``say``, e.g. ``print``).

    ``counts`` counts the events by their ``event`` text, for the final summary.
    A write that fails (disk full) is said once and the log goes on in memory.
    """

    def __init__(self, path: Path, say: Callable[[str], None] = print) -> None:
        self.path = Path(path)
        self.say = say
        self.events: list[Event] = []
        self.counts: Counter[str] = Counter()
        self._fd: int | None = None
        self.error: str | None = None
        try:
            new = not self.path.exists() or self.path.stat().st_size == 0
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
            if new:
                self._write(COLUMNS)
        except OSError as exc:
            self._failed(exc)

    def record(
        self,
        process: str,
        event: str,
        *,
        exit: str = "",
        action: str = "",
        sim_time: float | None = None,
    ) -> Event:
        """Log one event: on screen, in ``events.csv``, in :attr:`events`."""
        item = Event(process, event, exit, action, sim_time)
        self.events.append(item)
        self.counts[event] += 1
        when = "" if sim_time is None else f"{sim_time:.3f}"
        detail = f" ({exit})" if exit else ""
        then = f": {action}" if action else ""
        at = f" at sim time {sim_time:.2f} s" if sim_time is not None else ""
        self.say(f"launch: {process} {event}{detail}{at}{then}")
        stamp = datetime.now().astimezone().isoformat(timespec="milliseconds")
        self._write((stamp, when, process, event, exit, action))
        return item

    def _write(self, row: tuple[str, ...]) -> None:
        if self._fd is None:
            return
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(row)
        try:
            os.write(self._fd, buffer.getvalue().encode())
        except OSError as exc:
            self._failed(exc)

    def _failed(self, exc: OSError) -> None:
        self.error = f"{self.path}: {exc.strerror or exc}"
        self.say(f"launch: cannot write events.csv ({self.error}); events go on screen only")
        if self._fd is not None:
            os.close(self._fd)
        self._fd = None

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def parse_log_event(line: str) -> tuple[str, str] | None:
    """(event, action) of a log line holding :data:`~aes_ros.ros.interface.LOG_EVENT`
    (``… swarm event: <event>; <action>``), or None for any other line."""
    _, marker, text = line.partition(names.LOG_EVENT)
    if not marker:
        return None
    event, _, action = text.strip().partition("; ")
    return event.strip(), action.strip()


class _Logging(Protocol):
    name: str
    log: Path


class LogEvents:
    """Takes the events that processes report in their logs into an :class:`EventLog`.

    ``sources``: the names of the processes whose logs are read (the supervisor by
    default; reading every robot's log at each poll would cost more than it tells).
    Each log is read on from where the last :meth:`check` stopped, whole lines only,
    so every line is taken once, those of a restarted process (appended to the same
    log) too. ``sim_time`` gives the event's sim time: the latest the launcher saw.
    """

    def __init__(
        self,
        events: EventLog,
        sim_time: Callable[[], float | None],
        sources: Iterable[str] = (names.SUPERVISOR_NODE,),
    ) -> None:
        self.events = events
        self.sim_time = sim_time
        self.sources = frozenset(sources)
        self._offsets: dict[Path, int] = {}

    def check(self, children: Iterable[_Logging]) -> None:
        """Record the event lines the logs of ``children`` (of :attr:`sources`) got."""
        logs = {Path(c.log): c.name for c in children if c.name in self.sources}
        for log, name in logs.items():
            for line in self._new_lines(log):
                event = parse_log_event(line)
                if event is not None:
                    self.events.record(name, event[0], action=event[1], sim_time=self.sim_time())

    def _new_lines(self, log: Path) -> list[str]:
        offset = self._offsets.get(log, 0)
        try:
            if log.stat().st_size <= offset:
                return []
            with open(log, "rb") as fh:
                fh.seek(offset)
                data = fh.read()
        except OSError:
            return []
        end = data.rfind(b"\n") + 1  # whole lines only: the rest is still being written
        self._offsets[log] = offset + end
        return data[:end].decode(errors="replace").splitlines()


def fault_summary(events: list[Event], given_up: list[str]) -> str:
    """One line: how many processes died, were restarted and recovered, were given up."""
    died = [e for e in events if e.event in ("died", "cannot write the bag")]
    if not died:
        return "no faults"
    recovered = [e for e in events if e.event == "recovered"]
    per_process: dict[str, int] = {}
    for e in died:
        per_process[e.process] = per_process.get(e.process, 0) + 1
    listed = ", ".join(f"{name} {n}×" for name, n in per_process.items())
    gave_up = f", given up: {', '.join(given_up)}" if given_up else ""
    return (
        f"{len(died)} fault{'s' if len(died) != 1 else ''} ({listed}), "
        f"{len(recovered)} recovered{gave_up}; details in events.csv"
    )


def read_events(path: Path) -> list[dict[str, str]]:
    """The rows of an ``events.csv``."""
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))
