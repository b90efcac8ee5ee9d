"""The dashboard's view and request plumbing given what a careless or hostile publisher
sends: no robots, more than it draws, a size with no grid, an answer after the viewer
gave up. Each ends as an error the node logs, never an exception in its thread.

The same, end to end with real processes: tests/system/test_dashboard_bad_input.py.
"""

from __future__ import annotations

import concurrent.futures
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from aes_ros import scenario
from dashboard_node.requests import ControlRequests
from dashboard_node.view import MAX_ROBOTS, PosesError, SwarmView


def view_of(n: int) -> SwarmView:
    view = SwarmView(scenario.load("linear"))
    xy, yaw = scenario.load("linear").with_robots(n).initial_state(seed=1)
    view.on_poses(1.0, xy, yaw)
    return view


@pytest.mark.parametrize(
    ("n", "reason"), [(0, "no poses"), (MAX_ROBOTS + 1, "too many poses"), (10**5, "100000")]
)
def test_poses_of_no_robots_or_too_many_are_refused_and_the_last_kept(n: int, reason: str) -> None:
    view = view_of(9)
    before = view.frame()
    with pytest.raises(PosesError, match=reason):
        view.on_poses(2.0, np.zeros((n, 2)), np.zeros(n))
    assert view.n == 9 and view.t == 1.0
    assert view.frame() == before


@pytest.mark.parametrize("n", [1, 7, 1009, MAX_ROBOTS])
def test_any_size_up_to_the_maximum_is_drawn(n: int) -> None:
    """1009 is prime: no grid of at most 1000 columns holds it, so the sheet has no
    springs, and the robots are still drawn."""
    view = SwarmView(scenario.load("linear"))
    rng = np.random.default_rng(n)
    view.on_poses(1.0, rng.uniform(-5.0, 5.0, (n, 2)), rng.uniform(-3.0, 3.0, n))
    frame = view.frame()
    assert frame["n"] == n and len(frame["x"]) == len(frame["psi"]) == n
    assert all(math.isfinite(v) for v in frame["force"])
    json.dumps(frame, allow_nan=False)
    assert view.sheet_message()["n"] == n
    if n == 1009:
        assert view.sheet_message()["springs"] == []


def settle(future: concurrent.futures.Future, result: tuple[bool, str]) -> list[str]:
    warnings: list[str] = []
    ControlRequests._settle(SimpleNamespace(_warn=warnings.append), future, result)
    return warnings


def test_an_answer_after_the_viewer_gave_up_is_logged_not_raised() -> None:
    waiting: concurrent.futures.Future = concurrent.futures.Future()
    assert settle(waiting, (True, "supervisor: rotation_rate = 0.2")) == []
    assert waiting.result() == (True, "supervisor: rotation_rate = 0.2")

    given_up: concurrent.futures.Future = concurrent.futures.Future()
    given_up.cancel()  # what asyncio.wait_for does to it after CALL_TIMEOUT
    warnings = settle(given_up, (True, "alpha = 0.05: accepted by 10 of 10 nodes"))
    assert len(warnings) == 1 and warnings[0].startswith("late answer:"), warnings
    assert "accepted by 10 of 10" in warnings[0]
