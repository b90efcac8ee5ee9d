"""What the fused kernel (:mod:`aes_ros.kernel`) adds to a step for bodies and the IR rays.

The cut-offs of the candidate list the contacts and the rays share, the rays' reach, the
sensors' directions and the IR avoidance term of one robot, all numba code the kernel calls;
the contact rule (and the body centres) live in :mod:`aes_ros.contacts`, the rays in
:mod:`aes_ros.ir`, the term's definition in :mod:`aes_ros.avoidance`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from aes_ros.avoidance import AVOIDANCE_RANGE, IR_ANGLES
from aes_ros.contacts import CLOSE
from aes_ros.ir import mounting

#: cos and sin of the IR sensors' mounting angles (the avoidance term, aes_ros.avoidance).
_IR_COS, _IR_SIN = np.cos(IR_ANGLES), np.sin(IR_ANGLES)
#: The IR sensors' directions in the robot's frame, for the rays (math.cos and math.sin of
#: the angles, as aes_ros.ir.ray_distances computes them).
IR_MOUNT = mounting(IR_ANGLES)
#: With contacts and the IR rays on, the rays take their candidate pairs from the contact
#: list (those its last sweep found within reach), which then holds every pair within the
#: rays' reach (2 r + d_max) plus this margin [m] (the sweep's centres and the rays'
#: differ by rounding), and is made again once a body has moved _IR_LIST_SKIN radii
#: (_CONTACT_LIST_SKIN without the rays). Measured at 100 robots in the combined scenario:
#: the noise moves bodies about a skin in 3 steps at 0.5 radii, 7 at 1, so a list made at
#: twice that skin is made less than half as often, and sweeping its extra pairs costs less
#: than the lists saved; 2 radii were no faster.
LIST_MARGIN = 1e-6
_IR_LIST_SKIN = 1.5
_CONTACT_LIST_SKIN = 1.0


@njit(inline="always")
def avoidance_term(
    ranges: np.ndarray, i: int, w_o: float, c: float, s: float
) -> tuple[float, float]:
    """The IR repulsion f_o (:func:`aes_ros.avoidance.avoidance_force`) of robot i with
    ``ranges[i]`` (5,) [m] and heading (cos, sin) = (c, s), world frame (indexed, not a
    row view: a view per robot and step costs a reference count)."""
    bx = 0.0
    by = 0.0
    for a in range(ranges.shape[1]):
        if ranges[i, a] < AVOIDANCE_RANGE:
            push = min(1.0 - ranges[i, a] / AVOIDANCE_RANGE, 1.0)
            bx += push * _IR_COS[a]
            by += push * _IR_SIN[a]
    bx = -w_o * bx
    by = -w_o * by
    return c * bx - s * by, s * bx + c * by


@njit(inline="always")
def list_cutoffs(radius: float, sensing: bool) -> tuple[float, float]:
    """The cutoff ``near`` [m] and skin [m] of the kernel's candidate list of bodies of
    ``radius`` [m] (:func:`aes_ros.pair_list.kept_pairs`); with the IR rays on
    (``sensing``) the list holds every pair they can see."""
    if sensing:
        keep = max(CLOSE * radius + LIST_MARGIN, ray_reach(radius))
        skin = _IR_LIST_SKIN * radius
    else:
        keep = CLOSE * radius
        skin = _CONTACT_LIST_SKIN * radius
    return keep + 2.0 * skin, skin


@njit(inline="always")
def ray_reach(radius: float) -> float:
    """How close [m] two body centres of ``radius`` [m] must be for one robot's rays to
    meet the other's body (2 r + d_max), plus the list's rounding margin."""
    return 2.0 * radius + AVOIDANCE_RANGE + LIST_MARGIN
