"""Obstacle avoidance from the Mona's five IR ranges (pure numpy; docs/model.md, "Obstacle
avoidance").

Each sensor k at mounting angle φ_k (CCW from ahead) that reads a range d_k below the
sensing range d_max pushes the robot away from what it sees, linearly harder the closer
it is:

    f_o = −w_o Σ_k (1 − d_k / d_max)₊ (cos(θ + φ_k), sin(θ + φ_k))     (world frame)

This force is added to the AES force f (E4) before the noise and E5/E6, so an obstacle
ahead slows the robot and one to a side turns it away. Obstacle repulsion in AES from
the Mona's proximity sensors follows Liu, Turgut, Lennox and Arvin (2021); their
repulsion is a Lennard-Jones-like function of the distance, the linear ramp here is this
project's choice (bounded at contact, zero at and beyond d_max).
"""

from __future__ import annotations

import numpy as np

from aes_ros.mona.messages import IR_BEARINGS_DEG
from aes_ros.mona.sensors import IrModel

#: Mounting angles φ_k [rad] of IR sensors 0…4, CCW from ahead, in TELEMETRY's order
#: (the angles :mod:`aes_ros.ir` casts its rays at).
IR_ANGLES = np.radians(IR_BEARINGS_DEG)
#: Number of IR sensors of a Mona.
N_IR = len(IR_BEARINGS_DEG)
#: Sensing range d_max [m]: a reading at or beyond it is "nothing seen" (the IR model's
#: farthest range, which the bridge and the driver publish for nothing seen).
AVOIDANCE_RANGE = IrModel().max_range

_COS, _SIN = np.cos(IR_ANGLES), np.sin(IR_ANGLES)


def avoidance_force(
    ranges: np.ndarray,
    headings: np.ndarray | float,
    w_o: np.ndarray | float,
    d_max: float = AVOIDANCE_RANGE,
) -> np.ndarray:
    """Repulsion f_o from the IR ranges, world frame.

    Parameters
    ----------
    ranges : (..., 5) d_k [m], sensor order of :data:`IR_ANGLES`; NaN or anything
        ``>= d_max`` counts as nothing seen.
    headings : (...) θ [rad], CCW from +x.
    w_o : (...) or scalar avoidance weight.
    d_max : sensing range [m].

    Returns
    -------
    (..., 2) force; exactly zero where nothing is seen.
    """
    ranges = np.asarray(ranges, dtype=float)
    push = np.where(ranges < d_max, 1.0 - ranges / d_max, 0.0)  # (1 − d_k/d_max)₊; NaN → 0
    push = np.minimum(push, 1.0)  # a negative range is a sensor pressed against it
    # body frame: x ahead, y to the left
    bx = -np.asarray(w_o) * np.sum(push * _COS, axis=-1)
    by = -np.asarray(w_o) * np.sum(push * _SIN, axis=-1)
    c, s = np.cos(headings), np.sin(headings)
    return np.stack([c * bx - s * by, s * bx + c * by], axis=-1)


def ir_period_steps(rate: float, dt: float) -> int:
    """Control steps per IR reading, max(1, round(1/(rate·Δt))): the offline simulator
    casts the rays at the run steps that are multiples of it and holds them in between.

    rate : the scenario's ``ir_rate`` [Hz] (> 0). dt : Δt [s].
    """
    return max(1, round(1.0 / (rate * dt)))
