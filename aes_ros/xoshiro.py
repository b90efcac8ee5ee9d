"""The perception's random draws in numba: xoshiro256** and numpy's ziggurat.

:func:`camera_draws` makes the draws of one run's camera updates from that run's two
xoshiro256** generators (Blackman & Vigna 2018): standard normals for the position noise by
the 256-layer ziggurat numpy uses (Marsaglia & Tsang 2000), uniforms for the misses. The
offline kernel (:mod:`aes_ros.kernel`), :func:`aes_ros.perception.draw_camera` and
:class:`aes_ros.perception.PerceptionStream` all call it, so they see identical numbers;
each run draws in order on its core, so the numbers depend neither on the batch nor on the
number of threads (the generators and why: :mod:`aes_ros.perception`,
docs/model.md#perception-error).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, uint64

_ZIGGURAT_R = 3.6541528853610088  # where the ziggurat's tail begins


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marsaglia & Tsang's (2000) 256-layer ziggurat for N(0, 1) on 52-bit integers:
    thresholds k (256,) int64, widths w (256,) [1/2⁵²] and densities f (256,).

    The base layer starts at r = 3.6541528853610088 and every layer has the area v of
    the base strip and tail; v is computed from r (not Marsaglia & Tsang's rounded
    0.00492867323399) so that the top layer closes to 1e-13; the tables then equal
    numpy's ``ki_double``, ``wi_double``, ``fi_double`` to about 1e-13.
    """

    def f(x: float) -> float:
        return math.exp(-0.5 * x * x)

    r = _ZIGGURAT_R
    v = r * f(r) + math.sqrt(math.pi / 2.0) * math.erfc(r / math.sqrt(2.0))
    scale = 2.0**52
    k, w, fi = np.zeros(256, np.int64), np.zeros(256), np.zeros(256)
    q = v / f(r)
    k[0] = int(r / q * scale)
    w[0], w[255] = q / scale, r / scale
    fi[0], fi[255] = 1.0, f(r)
    x = x_up = r
    for i in range(254, 0, -1):
        x = math.sqrt(-2.0 * math.log(v / x + f(x)))
        k[i + 1] = int(x / x_up * scale)
        x_up = x
        fi[i], w[i] = f(x), x / scale
    return k, w, fi


_ZIGGURAT_K, _ZIGGURAT_W, _ZIGGURAT_F = _ziggurat_tables()
_TO_UNIT = 1.0 / 2.0**53  # 53 random bits to a double in [0, 1)
_MASK_52 = np.uint64((1 << 52) - 1)


@njit(inline="always")
def _xoshiro256(s0: int, s1: int, s2: int, s3: int) -> tuple[int, int, int, int, int]:
    """xoshiro256** (Blackman & Vigna 2018): the next 64-bit output and the new state."""
    out = s1 * uint64(5)
    out = ((out << uint64(7)) | (out >> uint64(57))) * uint64(9)
    t = s1 << uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = (s3 << uint64(45)) | (s3 >> uint64(19))
    return out, s0, s1, s2, s3


@njit(inline="always")
def _standard_normal(s0: int, s1: int, s2: int, s3: int) -> tuple[float, int, int, int, int]:
    """One N(0, 1) draw by the ziggurat and the new xoshiro256** state.

    numpy's variant: of one 64-bit output, 8 bits pick the layer, 1 the sign, 52 the
    abscissa; 98.8 % of draws end there, with no more output and no exp or log.
    """
    while True:
        bits, s0, s1, s2, s3 = _xoshiro256(s0, s1, s2, s3)
        layer = np.int64(bits & uint64(0xFF))
        negative = (bits >> uint64(8)) & uint64(1)
        mantissa = np.int64((bits >> uint64(9)) & _MASK_52)
        x = mantissa * _ZIGGURAT_W[layer]
        if mantissa < _ZIGGURAT_K[layer]:
            break
        if layer == 0:  # the tail beyond r (Marsaglia 1964)
            while True:
                bits, s0, s1, s2, s3 = _xoshiro256(s0, s1, s2, s3)
                xx = -math.log1p(-((bits >> uint64(11)) * _TO_UNIT)) / _ZIGGURAT_R
                bits, s0, s1, s2, s3 = _xoshiro256(s0, s1, s2, s3)
                yy = -math.log1p(-((bits >> uint64(11)) * _TO_UNIT))
                if yy + yy > xx * xx:
                    break
            x = _ZIGGURAT_R + xx
            break
        bits, s0, s1, s2, s3 = _xoshiro256(s0, s1, s2, s3)
        below = _ZIGGURAT_F[layer - 1] - _ZIGGURAT_F[layer]
        if below * ((bits >> uint64(11)) * _TO_UNIT) + _ZIGGURAT_F[layer] < math.exp(-0.5 * x * x):
            break
    return (-x if negative else x), s0, s1, s2, s3


@njit(cache=True)
def camera_draws(
    state: np.ndarray, noise_on: bool, miss_on: bool, noise: np.ndarray, uniforms: np.ndarray
) -> None:
    """The perception draws of M robot-frames (:mod:`aes_ros.perception`), in order.

    state : (2, 4) uint64, the xoshiro256** states of the noise and the miss
        generator of one run, advanced in place.
    noise : (M, 2) out: standard normals (x then y of each robot-frame), drawn from
        the noise generator if ``noise_on`` (else left as they are).
    uniforms : (M,) out: uniforms in [0, 1) from the miss generator if ``miss_on``.
    """
    if noise_on:
        s0, s1, s2, s3 = state[0, 0], state[0, 1], state[0, 2], state[0, 3]
        for i in range(noise.shape[0]):
            noise[i, 0], s0, s1, s2, s3 = _standard_normal(s0, s1, s2, s3)
            noise[i, 1], s0, s1, s2, s3 = _standard_normal(s0, s1, s2, s3)
        state[0, 0], state[0, 1], state[0, 2], state[0, 3] = s0, s1, s2, s3
    if miss_on:
        s0, s1, s2, s3 = state[1, 0], state[1, 1], state[1, 2], state[1, 3]
        for i in range(uniforms.shape[0]):
            bits, s0, s1, s2, s3 = _xoshiro256(s0, s1, s2, s3)
            uniforms[i] = (bits >> uint64(11)) * _TO_UNIT
        state[1, 0], state[1, 1], state[1, 2], state[1, 3] = s0, s1, s2, s3
