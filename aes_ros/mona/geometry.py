"""The Mona robot's geometry and motor limits, defined once (docs/design.md#mona).

The simulator's URDF (:mod:`sim_bridge.mona`) and the robot driver (:mod:`mona_driver`)
both take them from :class:`MonaGeometry`. :func:`wheels_from_twist` and
:func:`twist_from_wheels` convert a body twist to the wheel rim speeds [mm/s] of the
Mona link (docs/mona_protocol.md) and back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MonaGeometry:
    """Mona's dimensions [m], masses [kg] and motor limits (docs/design.md#mona defaults)."""

    body_radius: float = 0.040  #: body cylinder, Ø 80 mm
    body_height: float = 0.035  #: body cylinder height
    mass: float = 0.1  #: whole robot (body + wheels + caster)
    wheel_radius: float = 0.015  #: 12.8 mm in one public CAD model
    wheel_width: float = 0.005
    wheel_mass: float = 0.005  #: each wheel (part of ``mass``)
    wheel_separation: float = 0.078  #: distance between the wheels' mid-planes
    axle_offset: float = 0.018  #: axle behind the body centre
    caster_radius: float = 0.005  #: caster ball
    caster_offset: float = 0.025  #: caster ball centre ahead of the body centre
    caster_mass: float = 0.001  #: (part of ``mass``)
    ground_clearance: float = 0.003  #: gap under the body cylinder
    max_wheel_speed: float = 9.0  #: [rad/s]
    max_wheel_torque: float = 0.02  #: motor torque limit [N m]
    wheel_friction: float = 1.0  #: lateral (Coulomb) friction of tyres on the floor
    body_friction: float = 0.3  #: friction of body on body (robot-robot contacts)

    @property
    def body_z(self) -> float:
        """Height of the body centre above the ground [m]."""
        return self.ground_clearance + 0.5 * self.body_height

    @property
    def max_linear_speed(self) -> float:
        """Top forward speed [m/s] (both wheels at ``max_wheel_speed``)."""
        return self.max_wheel_speed * self.wheel_radius

    @property
    def max_angular_speed(self) -> float:
        """Top turn rate [rad/s] (wheels at ± ``max_wheel_speed``)."""
        return 2.0 * self.max_linear_speed / self.wheel_separation

    def wheel_speeds(
        self, linear: np.ndarray, angular: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Wheel angular speeds for body commands, saturated at ``max_wheel_speed``.

        Parameters
        ----------
        linear : (N,) forward speed u [m/s]. angular : (N,) turn rate [rad/s], CCW.

        Returns
        -------
        left, right : (N,) [rad/s], positive = rolling forward. When a wheel would
        exceed the limit both are scaled down by the same factor, so the robot
        keeps the commanded curvature and only slows down.
        """
        half = 0.5 * self.wheel_separation * np.asarray(angular, dtype=float)
        linear = np.asarray(linear, dtype=float)
        left = (linear - half) / self.wheel_radius
        right = (linear + half) / self.wheel_radius
        peak = np.maximum(np.abs(left), np.abs(right))
        scale = np.where(
            peak > self.max_wheel_speed, self.max_wheel_speed / np.maximum(peak, 1e-12), 1.0
        )
        return left * scale, right * scale

    @property
    def max_rim_speed_mm_s(self) -> int:
        """Top wheel rim speed [mm/s], rounded down: the clamp of a WHEELS command."""
        return int(self.max_linear_speed * 1000.0 + 1e-9)


def wheels_from_twist(
    v: float, omega: float, geometry: MonaGeometry | None = None
) -> tuple[int, int]:
    """Wheel rim speeds (left, right) [mm/s] for forward speed ``v`` [m/s] and turn rate
    ``omega`` [rad/s, CCW].

    left = v − ω·s/2, right = v + ω·s/2 (docs/mona_protocol.md, s = wheel separation), limited as in
    the simulator (:meth:`MonaGeometry.wheel_speeds`: both scaled down together, so the
    curvature is kept), rounded to mm/s and clamped to ± ``max_rim_speed_mm_s``.
    Non-finite input is the caller's to refuse (it gives a ValueError here).
    """
    g = geometry or MonaGeometry()
    left, right = g.wheel_speeds(np.array([v]), np.array([omega]))
    top = g.max_rim_speed_mm_s
    rim = [int(np.clip(round(float(w[0]) * g.wheel_radius * 1000.0), -top, top))
           for w in (left, right)]  # fmt: skip
    return rim[0], rim[1]


def twist_from_wheels(
    left: float, right: float, geometry: MonaGeometry | None = None
) -> tuple[float, float]:
    """Forward speed v [m/s] and turn rate ω [rad/s, CCW] of wheel rim speeds [mm/s]:
    v = (left + right)/2, ω = (right − left)/s."""
    g = geometry or MonaGeometry()
    left_m, right_m = 1e-3 * float(left), 1e-3 * float(right)
    return 0.5 * (left_m + right_m), (right_m - left_m) / g.wheel_separation
