"""The arena keeper's rule (:mod:`aes_ros.arena`), its parameters, and the route of its
events from the supervisor's log to ``events.csv``: plain pytest, no ROS."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from aes_ros import formations, model, scenario
from aes_ros.arena import (
    DEFAULT_MARGIN,
    OUTWARD,
    RELEASE_FACTOR,
    UNIT_DRIVE,
    WALLS,
    Arena,
    KeeperState,
    arena_or_none,
    keep_in_arena,
)
from aes_ros.params import MONA_RADIUS, PARAMS, ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros.launch.events import EventLog, LogEvents, parse_log_event, read_events

ARENA = Arena(-2.0, 2.0, -1.5, 1.5)
#: A 3 x 3 sheet at the arena's centre.
SHEET = formations.square_grid(3, 3, 0.2) - formations.square_grid(3, 3, 0.2).mean(axis=0)
#: Inward normal of each wall (the direction away from it).
INWARD = -OUTWARD
STEP = 0.005  # [m] per call when driving the sheet: 0.1 m/s at 20 Hz


def at(centre: tuple[float, float], sheet: np.ndarray = SHEET) -> np.ndarray:
    return sheet + np.asarray(centre)


def drive_until_keeper_acts(
    positions: np.ndarray, direction: np.ndarray, policy: str = "turn", max_steps: int = 2000
):
    """Move the sheet rigidly along ``direction`` by STEP per call until the keeper acts;
    (the decision, the positions it acted on, every clearance seen before)."""
    state = None
    seen = []
    unit = direction / np.linalg.norm(direction)
    for _ in range(max_steps):
        decision = keep_in_arena(positions, direction, ARENA, state, policy=policy)
        if decision.action != "keep":
            return decision, positions, np.array(seen)
        seen.append(ARENA.clearances(positions).min())
        state = decision.state
        positions = positions + STEP * unit
    raise AssertionError("the keeper never acted")


# ----------------------------------------------------------------------------- the rule


@pytest.mark.parametrize("direction", [(-1.0, 0.0), (0.0, 1.0), (0.7, -0.7), (0.0, 0.0)])
@pytest.mark.parametrize("policy", ["turn", "stop"])
def test_far_from_the_walls_the_command_stays(direction, policy) -> None:
    decision = keep_in_arena(at((0.3, -0.2)), direction, ARENA, policy=policy)
    assert decision.action == "keep"
    assert decision.direction == direction
    assert decision.state == KeeperState()


@pytest.mark.parametrize("wall", range(4), ids=WALLS)
@pytest.mark.parametrize("speed", [0.5, 1.0, 2.0])
def test_turns_before_the_first_robot_would_cross_each_wall(wall: int, speed: float) -> None:
    """Driving straight at a wall (from off-centre), the keeper turns as the first robot
    comes within the margin, no robot having come closer before; the new direction
    points inward and from the centroid to the centre, with the same |v_d|."""
    direction = OUTWARD[wall] * speed
    start = at((0.4, -0.3))
    decision, positions, seen = drive_until_keeper_acts(start, direction)
    clear = ARENA.clearances(positions)
    assert decision.action == "turn" and decision.wall == WALLS[wall]
    assert seen.min() >= DEFAULT_MARGIN  # nothing came within the margin before
    assert DEFAULT_MARGIN - STEP <= clear[:, wall].min() < DEFAULT_MARGIN
    assert decision.robot == int(np.argmin(clear[:, wall]))
    assert decision.clearance == pytest.approx(clear[:, wall].min())
    new = np.asarray(decision.direction)
    assert np.linalg.norm(new) == pytest.approx(speed)
    assert new @ OUTWARD[wall] < 0.0  # inward
    to_centre = ARENA.centre - positions.mean(axis=0)
    assert new / speed == pytest.approx(to_centre / np.linalg.norm(to_centre))
    assert decision.state.guarded[wall]


@pytest.mark.parametrize("n", [1, 7, 100])
def test_acts_for_any_swarm_size_and_on_the_robot_nearest_the_wall(n: int) -> None:
    rng = np.random.default_rng(n)
    positions = rng.uniform(-0.5, 0.5, size=(n, 2)) + np.array([1.0, 0.0])
    decision, positions, _ = drive_until_keeper_acts(positions, np.array([1.0, 0.2]))
    assert decision.action == "turn" and decision.wall == "east"
    assert decision.robot == int(np.argmax(positions[:, 0]))
    assert np.asarray(decision.direction) @ OUTWARD[1] < 0.0


def test_a_command_along_a_wall_or_away_from_it_is_kept() -> None:
    """Near the south wall: going along it or away from it is no threat; the wall is
    guarded meanwhile."""
    near_south = at((0.0, ARENA.y_min + 0.2 + DEFAULT_MARGIN / 2))
    for direction in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.5, 0.5)]:
        decision = keep_in_arena(near_south, direction, ARENA)
        assert decision.action == "keep", direction
        assert decision.state.guarded == (False, False, True, False)
    assert keep_in_arena(near_south, (1.0, -0.01), ARENA).action == "turn"


def test_in_a_corner_the_new_direction_points_inward_for_both_walls() -> None:
    corner = at((ARENA.x_min + 0.25, ARENA.y_max - 0.25))
    decision = keep_in_arena(corner, (-1.0, 1.0), ARENA)
    assert decision.action == "turn"
    assert decision.state.guarded == (True, False, False, True)
    new = np.asarray(decision.direction)
    assert new @ OUTWARD[0] < 0.0 and new @ OUTWARD[3] < 0.0
    # once turned, the keeper keeps the new command
    assert keep_in_arena(corner, new, ARENA, decision.state).action == "keep"


def test_a_swarm_wider_than_half_the_arena_is_turned_away_from_the_guarded_walls() -> None:
    """Near the west wall with its centroid east of the centre: the way to the centre
    points out through the west wall, so the keeper sends the swarm away from it."""
    wide = np.array([[ARENA.x_min + 0.1, 0.0], [ARENA.x_max - 0.5, 0.0], [1.0, 0.0]])
    assert wide.mean(axis=0)[0] > ARENA.centre[0]
    decision = keep_in_arena(wide, (-1.0, 0.0), ARENA)
    assert decision.action == "turn"
    assert decision.direction == pytest.approx((1.0, 0.0))


def test_a_swarm_spanning_the_arena_is_stopped_even_under_turn() -> None:
    """Robots near the west and the east wall: no direction is inward for both."""
    spanning = np.array([[ARENA.x_min + 0.05, 0.0], [ARENA.x_max - 0.05, 0.0]])
    decision = keep_in_arena(spanning, (1.0, 0.0), ARENA, policy="turn")
    assert decision.action == "stop" and decision.wall == "east"


def test_hysteresis_a_guarded_wall_is_freed_only_beyond_the_release_band() -> None:
    """A wall is guarded from the margin in and freed only once every robot is
    RELEASE_FACTOR margins from it: a robot jittering about the margin does not free
    it, and the keeper's own new command is never re-aimed meanwhile."""
    margin = DEFAULT_MARGIN
    release = RELEASE_FACTOR * margin

    def sheet_at(clearance: float) -> np.ndarray:  # the lead robot `clearance` from x_min
        return at((ARENA.x_min + clearance + 0.2, 0.0))

    decision = keep_in_arena(sheet_at(0.99 * margin), (-1.0, 0.0), ARENA)
    assert decision.action == "turn" and decision.state.guarded[0]
    new, state = decision.direction, decision.state
    rng = np.random.default_rng(0)
    for clearance in margin + rng.uniform(-0.02, 0.02, size=50):  # jitter about the margin
        decision = keep_in_arena(sheet_at(clearance), new, ARENA, state)
        assert decision.action == "keep" and decision.direction == new
        assert decision.state.guarded == (True, False, False, False)
        state = decision.state
    # between margin and release: still guarded, so pointing it out again is turned back
    between = sheet_at((margin + release) / 2)
    decision = keep_in_arena(between, (-1.0, 0.0), ARENA, state)
    assert decision.action == "turn" and decision.state.guarded[0]
    # the same place, never having come within the margin: nothing guarded, kept
    assert keep_in_arena(between, (-1.0, 0.0), ARENA).action == "keep"
    # beyond the release band: freed
    decision = keep_in_arena(sheet_at(release + 0.01), new, ARENA, state)
    assert decision.action == "keep" and decision.state == KeeperState()


def test_release_can_be_set_and_must_not_be_below_the_margin() -> None:
    lead_at = ARENA.x_min + 0.3  # the lead robot 0.3 m from the west wall
    positions = at((lead_at + 0.2, 0.0))
    state = KeeperState((True, False, False, False))
    kept = keep_in_arena(positions, (1.0, 0.0), ARENA, state, margin=0.1, release=0.5)
    assert kept.state.guarded[0]
    freed = keep_in_arena(positions, (1.0, 0.0), ARENA, state, margin=0.1, release=0.25)
    assert not freed.state.guarded[0]


@pytest.mark.parametrize("direction", [(-1.0, 0.0), (-0.3, 0.4), (0.0, 0.0)])
def test_stop_policy_stops_and_keeps_the_command(direction) -> None:
    positions = at((ARENA.x_min + 0.2 + 0.1, 0.0))  # lead robot 0.1 m from the west wall
    decision = keep_in_arena(positions, direction, ARENA, policy="stop")
    assert decision.action == "stop" and decision.wall == "west"
    assert decision.direction == direction
    assert "stopped" in decision.describe(direction)
    # stopped and re-enabled with the same command: stopped again (no hold on a stop)
    again = keep_in_arena(positions, direction, ARENA, decision.state, policy="stop")
    assert again.action == "stop"
    # pointed inward: kept
    assert keep_in_arena(positions, (1.0, 0.0), ARENA, decision.state, policy="stop").action == (
        "keep"
    )


def test_without_a_drive_a_swarm_near_a_wall_is_given_one_inward() -> None:
    """v_d = 0: the sheet drifts where v_0 takes it, so any guarded wall counts, and the
    turn gives it the unit drive towards the centre."""
    positions = at((0.0, ARENA.y_max - 0.2 - 0.1))
    decision = keep_in_arena(positions, (0.0, 0.0), ARENA)
    assert decision.action == "turn" and decision.wall == "north"
    new = np.asarray(decision.direction)
    assert np.linalg.norm(new) == pytest.approx(UNIT_DRIVE)
    assert new @ OUTWARD[3] < 0.0
    assert keep_in_arena(at((0.0, 0.0)), (0.0, 0.0), ARENA).action == "keep"


def test_the_rule_is_pure_and_checks_its_policy() -> None:
    positions = at((ARENA.x_min + 0.25, 0.3))
    before = positions.copy()
    first = keep_in_arena(positions, (-1.0, 0.0), ARENA)
    assert keep_in_arena(positions, (-1.0, 0.0), ARENA) == first
    np.testing.assert_array_equal(positions, before)
    with pytest.raises(ValueError, match="policy"):
        keep_in_arena(positions, (-1.0, 0.0), ARENA, policy="bounce")


def test_clearances_have_batch_axes_and_are_negative_outside() -> None:
    batch = np.stack([at((0.0, 0.0)), at((ARENA.x_max + 1.0, 0.0))])  # (2, 9, 2)
    clear = ARENA.clearances(batch)
    assert clear.shape == (2, 9, 4)
    assert (clear[0] > 0).all() and (clear[1][:, 1] < 0).all()
    np.testing.assert_allclose(clear[0, 4], [2.0, 2.0, 1.5, 1.5], atol=1e-12)


@pytest.mark.parametrize("policy", ["turn", "stop"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_in_the_loop_with_the_sheet_no_robot_leaves(policy: str, seed: int) -> None:
    """The linear setup on 9 robots (noise on, clipped to the Mona's limits) driving at a
    wall 0.4 m ahead, the keeper's command reaching the robots 0.25 s late: no robot's
    body (centre + radius) leaves the arena in 40 s, and under ``turn`` the swarm comes
    back from the wall."""
    scen = scenario.load("linear").with_robots(9)
    gains, dt, late = scen.gains, scen.dt, 5
    _, neighbors, rest = scen.sheet()
    pos, head = scen.initial_state(seed)
    arena = Arena(pos[:, 0].min() - 0.4, 2.0, -1.0, 1.0)
    rng = np.random.default_rng(seed)
    direction, enabled, state, queue = (-1.0, 0.0), True, None, []
    lowest, x_lowest = np.inf, np.inf
    for k in range(int(40.0 / dt)):
        told = queue[-1][1] if queue and queue[-1][1] is not None else direction
        decision = keep_in_arena(pos, told, arena, state, policy=policy)
        state = decision.state
        if decision.action == "turn":
            queue.append((k + late, decision.direction))
        elif decision.action == "stop" and enabled and not queue:
            queue.append((k + late, None))
        while queue and queue[0][0] <= k:
            change = queue.pop(0)[1]
            direction, enabled = (direction, False) if change is None else (change, enabled)
        force = model.total_forces(pos, neighbors, rest, gains, model.SwarmCommand(direction))
        u, w = model.motion_commands(force, head, gains, dt, model.draw_noise(rng, (9,)))
        u, w = model.clip_commands(u, w, scen.max_linear_speed, scen.max_angular_speed)
        if not enabled:
            u, w = 0.0 * u, 0.0 * w
        pos, head = model.unicycle_step(pos, head, u, w, dt)
        lowest = min(lowest, arena.clearances(pos).min())
        x_lowest = min(x_lowest, pos[:, 0].mean())
    assert lowest > MONA_RADIUS
    if policy == "turn":
        assert pos[:, 0].mean() > x_lowest + 0.5  # on its way back east
    else:
        assert not enabled


# ----------------------------------------------------------------------------- parameters


def test_arena_parameters_have_one_definition_with_ranges() -> None:
    spec = PARAMS["arena"]
    assert spec.default == () and arena_or_none(spec.default) is None
    assert arena_or_none([]) is None and arena_or_none("") is None
    assert arena_or_none("-1,2,-3,4") == Arena(-1.0, 2.0, -3.0, 4.0)
    assert arena_or_none([0, 1, 0, 1]).bounds == (0.0, 1.0, 0.0, 1.0)
    for bad in ([1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 1.0, 1.0], [0.0, 1.0, 2.0], [0, 1, np.nan, 2],
                [0.0, 1.0, 0.0, 1e9], "x", 3.0, [True, 1.0, 0.0, 1.0]):  # fmt: skip
        with pytest.raises(ParameterError, match="arena"):
            spec.validate(bad)
    assert PARAMS["arena_policy"].choices == ("turn", "stop")
    with pytest.raises(ParameterError, match="arena_policy"):
        PARAMS["arena_policy"].validate("bounce")
    margin = PARAMS["arena_margin"]
    assert margin.default == pytest.approx(0.04 + 0.13 * 1.0) == DEFAULT_MARGIN
    with pytest.raises(ParameterError, match="arena_margin"):
        margin.validate(0.0)
    with pytest.raises(ValueError, match="x_min < x_max"):
        Arena(1.0, 0.0, 0.0, 1.0)


def test_a_scenario_file_carries_the_arena(tmp_path: Path) -> None:
    path = tmp_path / "lab.yaml"
    path.write_text("arena: [-1.5, 1.5, -1.0, 1.0]\narena_policy: stop\narena_margin: 0.2\n")
    scen = scenario.load(path)
    assert scen.arena == (-1.5, 1.5, -1.0, 1.0)
    assert (scen.arena_policy, scen.arena_margin) == ("stop", 0.2)
    assert scenario.load("linear").arena == ()  # the packaged setups: no arena
    assert scenario.load("linear", {"arena": "0,3,-1,1"}).arena == (0.0, 3.0, -1.0, 1.0)
    path.write_text("arena: [1.5, -1.5, -1.0, 1.0]\n")
    with pytest.raises(ParameterError, match=r"lab\.yaml: arena"):
        scenario.load(path)


# ----------------------------------------------------------------------------- the event route


def test_a_logged_keeper_line_becomes_one_event(tmp_path: Path) -> None:
    """The supervisor's LOG_EVENT lines reach events.csv once each, only whole lines,
    and only from the processes read (the supervisor)."""
    decision = keep_in_arena(at((ARENA.x_min + 0.3, 0.0)), (-1.0, 0.0), ARENA)
    text = decision.describe((-1.0, 0.0))
    assert parse_log_event(f"[WARN] [12.5] [supervisor]: {names.LOG_EVENT} {text}") == (
        "arena keeper turned the swarm",
        text.partition("; ")[2],
    )
    assert parse_log_event("[INFO] [12.5] [supervisor]: receiving /swarm/poses") is None

    log = tmp_path / "supervisor.log"
    robots = tmp_path / "robots.log"
    children = [SimpleNamespace(name=names.SUPERVISOR_NODE, log=log),
                SimpleNamespace(name="robots_0", log=robots)]  # fmt: skip
    robots.write_text(f"{names.LOG_EVENT} not read; robots are not a source\n")
    log.write_text("[INFO] [1.0] [supervisor]: receiving /swarm/poses\n")
    events = EventLog(tmp_path / "events.csv", say=lambda _line: None)
    watcher = LogEvents(events, sim_time=lambda: 4.25)
    watcher.check(children)
    assert events.events == []
    with open(log, "a") as fh:
        fh.write(f"[WARN] [2.0] [supervisor]: {names.LOG_EVENT} {text}\n")
        fh.write(f"[WARN] [2.1] [supervisor]: {names.LOG_EVENT} half a li")
    watcher.check(children)
    watcher.check(children)
    assert [(e.process, e.event) for e in events.events] == [
        (names.SUPERVISOR_NODE, "arena keeper turned the swarm")
    ]
    with open(log, "a") as fh:
        fh.write("ne; done\n")
    watcher.check(children)
    events.close()
    rows = read_events(tmp_path / "events.csv")
    assert [(r["process"], r["event"], r["action"]) for r in rows] == [
        (names.SUPERVISOR_NODE, "arena keeper turned the swarm", text.partition("; ")[2]),
        (names.SUPERVISOR_NODE, "half a line", "done"),
    ]
    assert rows[0]["sim_time"] == "4.250"
