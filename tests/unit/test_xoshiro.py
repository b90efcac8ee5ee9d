"""The perception's generators (aes_ros.xoshiro): the uniforms are xoshiro256**'s stream,
and the ziggurat's normals are N(0, 1) out to the tail."""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from aes_ros.perception import perception_state
from aes_ros.xoshiro import camera_draws

MASK = (1 << 64) - 1


def reference_xoshiro256(state: list[int], n: int) -> list[int]:
    """xoshiro256** as Blackman & Vigna publish it (xoshiro256starstar.c), on Python ints."""

    def rotl(x: int, k: int) -> int:
        return ((x << k) | (x >> (64 - k))) & MASK

    s = list(state)
    out = []
    for _ in range(n):
        out.append(rotl((s[1] * 5) & MASK, 7) * 9 & MASK)
        t = (s[1] << 17) & MASK
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = rotl(s[3], 45)
    return out


def test_the_miss_uniforms_are_the_reference_xoshiro256_stream() -> None:
    state = perception_state(7)
    start = [int(v) for v in state[1]]
    uniforms = np.empty(1000)
    camera_draws(state, False, True, np.empty((0, 2)), uniforms)
    expected = [(bits >> 11) * 2.0**-53 for bits in reference_xoshiro256(start, 1000)]
    np.testing.assert_array_equal(uniforms, expected)
    # the state is advanced: the next draws go on with the same stream
    more = np.empty(5)
    camera_draws(state, False, True, np.empty((0, 2)), more)
    tail = reference_xoshiro256(start, 1005)[1000:]
    np.testing.assert_array_equal(more, [(bits >> 11) * 2.0**-53 for bits in tail])


def test_the_noise_normals_are_standard_normal_out_to_the_ziggurat_tail() -> None:
    """Two million draws: a Kolmogorov-Smirnov test against N(0, 1), and the rate of
    draws beyond r = 3.654 (the ziggurat's base layer and tail, drawn by a separate
    branch) within four binomial standard deviations of 2 (1 - Φ(r))."""
    state = perception_state(3)
    normals = np.empty((1_000_000, 2))
    camera_draws(state, True, False, normals, np.empty(0))
    z = normals.ravel()
    assert stats.kstest(z, "norm").pvalue > 1e-3
    r = 3.6541528853610088
    p = 2.0 * stats.norm.sf(r)
    expected = p * len(z)
    assert abs(np.count_nonzero(np.abs(z) > r) - expected) < 4.0 * math.sqrt(expected)
    assert abs(np.count_nonzero(z > r) - np.count_nonzero(z < -r)) < 4.0 * math.sqrt(expected)
