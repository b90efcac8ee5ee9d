"""One definition of every model and scenario parameter (docs/design.md#model, #scenarios, #mona).

Each :class:`~aes_ros.param_spec.ParamSpec` carries the name, default, allowed range, unit
and a description, and checks a value (a bad one raises :class:`ParameterError`; both are
defined in :mod:`aes_ros.param_spec` and importable from here). The scenario loader, the
``--set`` option of the CLI, the ROS nodes' ``ParameterDescriptor`` s and the README table
are all built from :data:`PARAMS`, so a range or a default is changed in exactly one place.
"""

from __future__ import annotations

from typing import Any

from aes_ros.param_spec import ParameterError, ParamSpec


def _p(
    name: str, default: Any, kind: str, description: str, unit: str = "", **kw: Any
) -> ParamSpec:
    return ParamSpec(name, default, kind, description, unit, **kw)


#: The Mona's top forward speed [m/s] (9 rad/s × 15 mm) and body radius [m] (Ø 80 mm),
#: docs/design.md#mona
MONA_TOP_SPEED, MONA_RADIUS = 0.13, 0.04
#: The arena keeper's reaction time [s]: from a robot entering the margin to the sheet
#: no longer moving outward (derivation in :mod:`aes_ros.arena`). The default margin is
#: the distance a robot covers in it at top speed, plus its radius.
ARENA_REACTION_TIME = 1.0

#: Every scenario parameter, in the order the docs list them. Defaults are the
#: paper's Table 1 (docs/design.md#scenarios), with the rotation rate in our counter-clockwise
#: convention (the paper's ω = 0.7 clockwise is ω = -0.7 here).
PARAMS: dict[str, ParamSpec] = {
    p.name: p
    for p in [
        # --- formation (docs/design.md#sheet, #scenarios) ---
        _p(
            "formation",
            "grid",
            "str",
            "initial formation: square grid, hexagonal sheet or CSV file",
            choices=("grid", "hex", "csv"),
        ),
        _p("rows", 10, "int", "grid rows", low=1, high=1000),
        _p("cols", 10, "int", "grid columns", low=1, high=1000),
        _p("rings", 5, "int", "hexagonal sheet rings s (N = 3s(s+1)+1)", low=0, high=100),
        _p("formation_file", "", "str", "CSV file of nominal positions x,y (formation: csv)"),
        _p(
            "spacing",
            0.2,
            "float",
            "nominal distance between neighbours d_init",
            "m",
            low=0.01,
            high=100.0,
        ),
        _p(
            "neighbor_factor",
            1.01,
            "float",
            "neighbour radius as a multiple of spacing (1.01: 4-neighbourhood on a grid, "
            "1.5: with diagonals)",
            low=0.5,
            high=10.0,
        ),
        _p(
            "perturbation",
            0.1,
            "float",
            "initial offset of each robot per axis, uniform up to this fraction of spacing",
            low=0.0,
            high=0.5,
        ),
        # --- gains and noise (docs/design.md#extensions, #motion) ---
        _p("alpha", 0.066, "float", "translational gain α (E5)", "m/(s·N)", low=0.0, high=10.0),
        _p("beta", 0.97, "float", "rotational gain β (E6)", "rad/(s·N)", low=0.0, high=50.0),
        _p("k", 1.28, "float", "spring stiffness k (E1)", "N", low=0.0, high=100.0),
        _p("v0", 0.05, "float", "forward bias speed v_0", "m/s", low=-1.0, high=1.0),
        _p("w_l", 0.8, "float", "linear-drive weight w_l (E2)", low=0.0, high=10.0),
        _p("w_r", 1.0, "float", "rotation weight w_r (E3)", low=0.0, high=10.0),
        _p("d_r", 0.5, "float", "sensing-noise strength D_r", "N·s^0.5", low=0.0, high=10.0),
        _p(
            "d_theta",
            0.02,
            "float",
            "actuation-noise strength D_θ",
            "rad/s^0.5",
            low=0.0,
            high=10.0,
        ),
        _p(
            "w_o",
            0.0,
            "float",
            "obstacle-avoidance weight w_o: repulsion from the five IR ranges, added to the "
            "force (docs/model.md, Obstacle avoidance); 0: off",
            "N",
            low=0.0,
            high=10.0,
        ),
        _p(
            "ir_rate",
            20.0,
            "float",
            "IR readings per second the avoidance term acts on (a Mona's TELEMETRY rate): the "
            "offline simulator casts the rays every round(1/(ir_rate·Δt)) steps and holds "
            "them in between; the bridge's ir_rate defaults to it",
            "Hz",
            low=0.1,
            high=1000.0,
        ),
        # --- swarm command (docs/design.md#extensions) ---
        _p(
            "direction",
            (-1.0, 0.0),
            "vec2",
            "desired direction v_d (world frame; length scales the drive, 0,0 switches it off)",
            low=-10.0,
            high=10.0,
        ),
        _p(
            "omega",
            -0.7,
            "float",
            "rotation rate ω, counter-clockwise positive (REP-103)",
            "rad/s",
            low=-10.0,
            high=10.0,
        ),
        _p(
            "rotation_center",
            "centroid",
            "center",
            "rotation centre x_c: the live centroid or a fixed point",
            "m",
            low=-1e4,
            high=1e4,
        ),
        # --- integration and robot limits (docs/design.md#motion, #mona) ---
        _p("dt", 0.05, "float", "Euler time step Δt (20 Hz control)", "s", low=1e-4, high=1.0),
        _p("duration", 30.0, "float", "run length t_f", "s", low=0.0, high=1e5),
        _p("clip", False, "bool", "clip commands to the robot's limits"),
        _p(
            "max_linear_speed",
            MONA_TOP_SPEED,
            "float",
            "Mona's top forward speed (9 rad/s × 15 mm)",
            "m/s",
            low=0.0,
            high=10.0,
        ),
        _p(
            "max_angular_speed",
            3.4,
            "float",
            "Mona's top turn rate (2·0.13 m/s / 78 mm)",
            "rad/s",
            low=0.0,
            high=100.0,
        ),
        # --- perception error of an overhead tracker (offline simulator; aes_ros.perception) ---
        _p(
            "perception_sigma",
            0.0,
            "float",
            "tracker position noise σ_p: Gaussian, per axis, added to every perceived position "
            "at each camera update (headings exact); 0: exact positions",
            "m",
            low=0.0,
            high=0.1,
        ),
        _p(
            "perception_delay",
            0.0,
            "float",
            "tracker latency τ: robots see the poses as they were round(τ/Δt) steps ago",
            "s",
            low=0.0,
            high=2.0,
        ),
        _p(
            "perception_rate",
            0.0,
            "float",
            "camera frame rate f_cam: poses refreshed every round(1/(f_cam·Δt)) steps and held "
            "in between; 0: every control step",
            "Hz",
            low=0.0,
            high=1000.0,
        ),
        _p(
            "perception_miss",
            0.0,
            "float",
            "probability that a camera update misses a robot, which then keeps its last "
            "perceived pose",
            low=0.0,
            high=0.99,
        ),
        # --- arena keeper (supervisor; aes_ros.arena) ---
        _p(
            "arena",
            (),
            "rect",
            "arena rectangle in the world frame (odom) the supervisor keeps the swarm in "
            "(e.g. the camera's view); empty: no arena keeper",
            "m",
            low=-1e4,
            high=1e4,
        ),
        _p(
            "arena_policy",
            "turn",
            "str",
            "what the arena keeper does when the swarm heads out of the arena: turn v_d "
            "towards the arena's centre, or stop (disable) the robots",
            choices=("turn", "stop"),
        ),
        _p(
            "arena_margin",
            round(MONA_RADIUS + MONA_TOP_SPEED * ARENA_REACTION_TIME, 4),
            "float",
            "distance from a wall at which the arena keeper acts (robot radius + top speed "
            "× reaction time 1 s); freed again at twice this distance",
            "m",
            low=0.001,
            high=100.0,
        ),
        # --- bodies: contacts, walls and obstacles (aes_ros.contacts) ---
        _p(
            "contacts",
            True,
            "bool",
            "robots are discs of the body radius that push each other apart and stop at "
            "walls and obstacles; false: they pass through each other and everything",
        ),
        _p(
            "walls",
            (),
            "rect",
            "walls around the arena (world frame, odom): a rectangle the robots' bodies stay "
            "inside when contacts are on; empty: no walls",
            "m",
            low=-1e4,
            high=1e4,
        ),
        _p(
            "obstacles",
            (),
            "obstacles",
            "fixed obstacles, circles x,y,r and boxes x_min,x_max,y_min,y_max, that the "
            "robots' bodies cannot enter when contacts are on; empty: none",
            "m",
            low=-1e4,
            high=1e4,
        ),
    ]
}


def validate_params(values: dict[str, Any], source: str = "") -> dict[str, Any]:
    """Validate a mapping of parameter names to values.

    Raises ParameterError naming the first unknown key or bad value; ``source``
    (e.g. a file name) prefixes the message.
    """
    prefix = f"{source}: " if source else ""
    out: dict[str, Any] = {}
    for key, value in values.items():
        if key not in PARAMS:
            raise ParameterError(f"{prefix}unknown parameter {key!r}; allowed: {', '.join(PARAMS)}")
        try:
            out[key] = PARAMS[key].validate(value)
        except ParameterError as exc:
            raise ParameterError(prefix + str(exc)) from None
    return out


def markdown_table(names: list[str] | None = None) -> str:
    """The parameter table for the README (name, default, unit, range, description)."""
    rows = ["| name | default | unit | allowed | description |", "|---|---|---|---|---|"]
    for spec in PARAMS.values():
        if names is None or spec.name in names:
            rows.append(
                f"| `{spec.name}` | {spec.default} | {spec.unit} | {spec.allowed()} | "
                f"{spec.description} |"
            )
    return "\n".join(rows)
