"""The Mona robot (docs/design.md#mona) as a URDF generated from its parameters.

Frames (REP-105): ``base_link`` lies on the ground under the midpoint of the
wheel axle. That point is the one that moves as a unicycle (it never moves
sideways), so it is the robot's position in ``/swarm/poses`` and ``odom``. The
body cylinder's centre is ``axle_offset`` ahead of it; the caster ball is in
front of the body centre.

Every quantity is a field of :class:`MonaGeometry` (defined in
:mod:`aes_ros.mona.geometry`, shared with the robot driver), so e.g. the 12.8 mm wheel
of one public CAD model is ``MonaGeometry(wheel_radius=0.0128)``.
"""

from __future__ import annotations

import math

from aes_ros.mona.geometry import MonaGeometry


def _cylinder_inertia(mass: float, radius: float, length: float) -> tuple[float, float, float]:
    """(ixx, iyy, izz) of a solid cylinder along z [kg m²]."""
    side = mass * (3.0 * radius**2 + length**2) / 12.0
    return side, side, 0.5 * mass * radius**2


def _inertial(
    mass: float,
    xyz: tuple[float, float, float],
    ixx: float,
    iyy: float,
    izz: float,
    rpy: str = "0 0 0",
) -> str:
    x, y, z = xyz
    return (
        f'<inertial><origin xyz="{x:.6g} {y:.6g} {z:.6g}" rpy="{rpy}"/><mass value="{mass:.6g}"/>'
        f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/>'
        "</inertial>"
    )


def _shape(
    kind: str,
    geometry: str,
    xyz: tuple[float, float, float],
    rpy: str = "0 0 0",
    material: str = "",
) -> str:
    x, y, z = xyz
    return (
        f'<{kind}><origin xyz="{x:.6g} {y:.6g} {z:.6g}" rpy="{rpy}"/>'
        f"<geometry>{geometry}</geometry>{material}</{kind}>"
    )


def urdf(geometry: MonaGeometry | None = None, name: str = "mona") -> str:
    """The Mona robot as a URDF document.

    Links: ``base_link`` (frame on the ground under the axle midpoint; carries the
    body cylinder, centre ``axle_offset`` ahead), ``left_wheel`` / ``right_wheel``
    (continuous joints about +y: a positive joint velocity rolls forward) and
    ``caster`` (fixed ball in front; give it zero friction in the simulator).
    """
    g = geometry or MonaGeometry()
    body_mass = g.mass - 2.0 * g.wheel_mass - g.caster_mass
    if body_mass <= 0.0:
        raise ValueError("mass: must exceed the mass of the wheels and the caster")
    body = (g.axle_offset, 0.0, g.body_z)
    cyl = f'<cylinder radius="{g.body_radius:.6g}" length="{g.body_height:.6g}"/>'
    grey = '<material name="grey"><color rgba="0.75 0.75 0.78 1"/></material>'
    black = '<material name="black"><color rgba="0.1 0.1 0.1 1"/></material>'
    parts = [
        f'<?xml version="1.0"?>\n<robot name="{name}">',
        '<link name="base_link">',
        _inertial(body_mass, body, *_cylinder_inertia(body_mass, g.body_radius, g.body_height)),
        _shape("visual", cyl, body, material=grey),
        _shape("collision", cyl, body),
        "</link>",
    ]
    wheel_geom = f'<cylinder radius="{g.wheel_radius:.6g}" length="{g.wheel_width:.6g}"/>'
    # Collision: a ball of the wheel's radius. It touches the floor at the same
    # point as the cylinder, and the joint lets it roll only about the axle; one
    # contact point instead of a cylinder's two makes 100 robots at 240 Hz ~1.5x
    # faster (bench/bench_ros.py --physics).
    wheel_ball = f'<sphere radius="{g.wheel_radius:.6g}"/>'
    wheel_i = _cylinder_inertia(g.wheel_mass, g.wheel_radius, g.wheel_width)
    # The wheel cylinder's axis (z) is turned onto the joint axis (y).
    turn = f"{-math.pi / 2:.9g} 0 0"
    for side, sign in (("left", 1.0), ("right", -1.0)):
        parts += [
            f'<link name="{side}_wheel">',
            _inertial(g.wheel_mass, (0.0, 0.0, 0.0), *wheel_i, rpy=turn),
            _shape("visual", wheel_geom, (0.0, 0.0, 0.0), turn, black),
            _shape("collision", wheel_ball, (0.0, 0.0, 0.0)),
            "</link>",
            f'<joint name="{side}_wheel_joint" type="continuous">'
            f'<parent link="base_link"/><child link="{side}_wheel"/>'
            f'<origin xyz="0 {sign * 0.5 * g.wheel_separation:.6g} {g.wheel_radius:.6g}" '
            'rpy="0 0 0"/><axis xyz="0 1 0"/>'
            f'<limit effort="{g.max_wheel_torque:.6g}" velocity="{g.max_wheel_speed:.6g}"/>'
            "</joint>",
        ]
    ball = f'<sphere radius="{g.caster_radius:.6g}"/>'
    ci = 0.4 * g.caster_mass * g.caster_radius**2
    parts += [
        '<link name="caster">',
        _inertial(g.caster_mass, (0.0, 0.0, 0.0), ci, ci, ci),
        _shape("visual", ball, (0.0, 0.0, 0.0), material=black),
        _shape("collision", ball, (0.0, 0.0, 0.0)),
        "</link>",
        '<joint name="caster_joint" type="fixed"><parent link="base_link"/>'
        '<child link="caster"/>'
        f'<origin xyz="{g.axle_offset + g.caster_offset:.6g} 0 {g.caster_radius:.6g}" '
        'rpy="0 0 0"/></joint>',
        "</robot>\n",
    ]
    return "\n".join(parts)
