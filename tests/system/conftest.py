"""Fixtures of the system tests: an isolated ROS 2 environment per test, its
processes, and the test's rclpy probe.

``ros_env`` gives each test its own ``ROS_DOMAIN_ID`` (held with a file lock so that
parallel pytest runs on one machine never share one) and keeps discovery on this
host. ``spawn`` starts real processes in their own process groups and guarantees
they are stopped (SIGINT, then SIGKILL) and Fast DDS shared-memory leftovers are
cleaned when the test ends, pass or fail; a failing test's report shows the end of
every process's log. ``probe`` is a started :class:`helpers.probe.Probe`, closed at
teardown. Every test collected here carries the marker ``ros``.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers.probe import Probe
from helpers.ros_env import Processes, reserved_domain_id, ros_variables

HERE = Path(__file__).parent


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if HERE in item.path.parents:
            item.add_marker(pytest.mark.ros)


@pytest.fixture
def ros_env(monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, str]]:
    """Environment for this test's ROS processes (also applied to the test process)."""
    with reserved_domain_id() as domain:
        for key, value in ros_variables(domain).items():
            monkeypatch.setenv(key, value)
        yield dict(os.environ)


@pytest.fixture
def spawn(ros_env: dict[str, str], tmp_path: Path) -> Iterator[Processes]:
    """Start processes for a test; they are stopped when the test ends.

    Usage: ``spawn.start("aes-sim-bridge", "--ros-args", "-p", "lockstep:=true")``.
    """
    procs = Processes(ros_env, tmp_path / "logs")
    try:
        yield procs
    finally:
        procs.stop_all()


@pytest.fixture
def probe(ros_env: dict[str, str]) -> Iterator[Probe]:
    """The test's rclpy node, spinning in the background (in the test's domain)."""
    node = Probe()
    try:
        yield node
    finally:
        node.close()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """A failing test's report gets the end of every log of its processes."""
    report = yield
    procs = getattr(item, "funcargs", {}).get("spawn")
    if report.failed and isinstance(procs, Processes) and procs.procs:
        report.sections.append(("process logs", procs.logs()))
    return report
