"""What the Mona's IR sensors read: exact ray distances through noise and the response curve.

:func:`ir_response` adds Gaussian noise to a distance of :mod:`aes_ros.ir`'s rays and passes
it through the sensor's response curve (:class:`aes_ros.mona.sensors.IrModel`: to a raw
10-bit ADC reading and back), so a simulated reading is quantised like the Mona driver's; it
is a numba kernel the bridge calls on pybullet's rays. :func:`ir_ranges` is the numpy entry
point: every robot's rays and readings. docs/model.md, "IR proximity sensors".
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from aes_ros.ir import IR_ANGLES, NO_WALLS, ray_distances
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.sensors import IrModel


@njit(cache=True)
def ir_response(
    distances: np.ndarray,
    normals: np.ndarray,
    sigma: float,
    gain: float,
    offset: float,
    min_range: float,
    max_range: float,
    falling: bool,
    quantise: bool,
    out: np.ndarray,
) -> None:
    """Fill ``out`` with the readings [m] of the true ``distances`` (any shape, same as out).

    A sensor that sees something (distance < max_range) reads the distance plus
    ``sigma`` × ``normals`` (standard normal draws of the same shape), then, with
    ``quantise``, that distance turned into the raw ADC reading the IR model
    (:class:`aes_ros.mona.sensors.IrModel`: signal = offset + gain / range, raw = 1023 −
    signal when ``falling``) would give, rounded to a whole count in [0, 1023], and back
    through the model; clipped to [min_range, max_range]. Nothing seen reads max_range.
    """
    d, z, o = distances.ravel(), normals.ravel(), out.ravel()
    for i in range(len(d)):
        if d[i] >= max_range:
            o[i] = max_range
            continue
        r = d[i] + sigma * z[i]
        if quantise:
            signal = offset + gain / max(r, 1e-9)
            raw = min(max(round(1023.0 - signal if falling else signal), 0.0), 1023.0)
            excess = (1023.0 - raw if falling else raw) - offset
            r = gain / excess if excess > 0.0 else max_range
        o[i] = min(max(r, min_range), max_range)


@dataclass(frozen=True)
class IrResponse:
    """How a sensor turns a distance into a reading: noise and the response curve.

    noise : standard deviation [m] of Gaussian noise on a distance (before quantising).
    model : the response curve (the Mona driver's ``ir_*`` parameters).
    quantise : pass each reading through a whole raw ADC count (False: only clip).
    """

    noise: float = 0.0
    model: IrModel = field(default_factory=IrModel)
    quantise: bool = True


def _obstacle_array(values: np.ndarray | None, columns: int) -> np.ndarray:
    if values is None:
        return np.zeros((0, columns))
    return np.ascontiguousarray(values, dtype=float).reshape(-1, columns)


def ir_ranges(
    positions: np.ndarray,
    headings: np.ndarray,
    *,
    geometry: MonaGeometry | None = None,
    walls: np.ndarray | None = None,
    circles: np.ndarray | None = None,
    boxes: np.ndarray | None = None,
    response: IrResponse | None = None,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Readings [m] of every robot's five IR sensors, (N, 5), order of :data:`IR_ANGLES`.

    Parameters
    ----------
    positions : (N, 2) pose points [m; odom]. headings : (N,) [rad].
    geometry : the robot's body (``body_radius``, ``axle_offset``).
    walls : (4,) x_min, x_max, y_min, y_max of the arena (robots inside), or None.
    circles : (M, 3) x, y, r [m] obstacles, or None. boxes : (L, 4) x_min, x_max, y_min,
        y_max [m] obstacles, or None.
    response : noise and response curve; None = exact distances clipped to
        ``IrModel().max_range`` (no noise, no quantising).
    rng : where the noise comes from (needed if ``response.noise`` > 0).

    Returns
    -------
    (N, 5) readings; a sensor that sees nothing reads ``max_range``, and so does every
    sensor of a robot whose pose is not finite (a simulated run that diverged), which no
    other robot sees.
    """
    g = geometry or MonaGeometry()
    positions = np.ascontiguousarray(positions, dtype=float).reshape(-1, 2)
    headings = np.ascontiguousarray(headings, dtype=float).reshape(-1)
    walls = NO_WALLS if walls is None else np.ascontiguousarray(walls, dtype=float).reshape(-1)
    if len(walls) not in (0, 4):
        raise ValueError(f"walls: {len(walls)} numbers; give x_min, x_max, y_min, y_max")
    model = IrModel() if response is None else response.model
    out = np.empty((len(headings), len(IR_ANGLES)))
    ray_distances(
        positions,
        headings,
        g.body_radius,
        g.axle_offset,
        IR_ANGLES,
        model.max_range,
        walls,
        _obstacle_array(circles, 3),
        _obstacle_array(boxes, 4),
        out,
    )
    if response is None:
        return out
    if response.noise > 0.0 and rng is None:
        raise ValueError("ir_ranges: noise needs an rng (numpy.random.Generator)")
    normals = rng.standard_normal(out.shape) if response.noise > 0.0 else np.zeros(out.shape)
    readings = np.empty_like(out)
    ir_response(
        out,
        normals,
        response.noise,
        model.gain,
        model.offset,
        model.min_range,
        model.max_range,
        model.falling,
        response.quantise,
        readings,
    )
    return readings
