"""Perception error: what an overhead camera and marker tracker show the robots.

The robots see the world through one shared **perceived frame** per run: perceived
positions P̃ (N, 2) [m; odom] and headings Θ̃ (N,) [rad]. They compute their forces
(E1–E4, the live centroid included) from P̃ and project them on Θ̃_i (E5, E6); the
unicycle step moves the *true* state, and the metrics (E7–E9) stay on it.

Four parameters, all off by default: ``perception_sigma`` σ_p [m] (Gaussian noise per
axis at each camera update), ``perception_delay`` τ [s] (the state round(τ/Δt) steps
ago), ``perception_rate`` f_cam [Hz] (refreshed every round(1/(f_cam·Δt)) steps, held
between; 0 = every step) and ``perception_miss`` (each robot missed per refresh, keeping
its last perceived pose; nobody at step 0). Run ``seed`` draws them from two generators
of its own, never the run's, through one compiled :func:`aes_ros.xoshiro.camera_draws`
shared by the kernel, :func:`draw_camera` and :class:`PerceptionStream`, so all three
see identical numbers (docs/model.md#perception-error).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PerceptionSettings:
    """The four perception parameters (module docstring); defaults: off."""

    sigma: float = 0.0  #: σ_p [m], position noise std per axis
    delay: float = 0.0  #: τ [s]
    rate: float = 0.0  #: f_cam [Hz]; 0 = every control step
    miss: float = 0.0  #: probability of a robot being missed at a refresh

    @classmethod
    def from_mapping(cls, values: dict) -> PerceptionSettings:
        """The ``perception_*`` entries of a larger mapping (e.g. a scenario's values)."""
        return cls(
            **{
                name: float(values[f"perception_{name}"])
                for name in ("sigma", "delay", "rate", "miss")
                if f"perception_{name}" in values
            }
        )

    def enabled(self, dt: float) -> bool:
        """Whether the perceived frame can differ from the true state at step ``dt`` [s]."""
        return (
            self.sigma > 0.0
            or self.miss > 0.0
            or delay_steps(self.delay, dt) > 0
            or camera_period_steps(self.rate, dt) > 1
        )


def camera_period_steps(rate: float, dt: float) -> int:
    """Control steps per camera frame, m = max(1, round(1/(f_cam·Δt))); 1 when f_cam = 0.

    rate : f_cam [Hz]. dt : Δt [s].
    """
    if rate <= 0.0:
        return 1
    return max(1, round(1.0 / (rate * dt)))


def delay_steps(delay: float, dt: float) -> int:
    """The latency in control steps, D = round(τ/Δt). delay : τ [s]. dt : Δt [s]."""
    return round(delay / dt)


def ring_slots(step: int, delay: int) -> tuple[int, int]:
    """Where the true state of ``step`` goes in a ring of the last D+1 states, and
    where the state shown at ``step`` is: (step mod (D+1), (step + 1) mod (D+1)).

    The slot read holds the state of step − D, or, before step D, whatever the ring
    was filled with (the initial state). ``delay`` : D [steps].
    """
    return step % (delay + 1), (step + 1) % (delay + 1)


def refresh_steps(first: int, n: int, period: int) -> np.ndarray:
    """The refresh steps (multiples of ``period``) among steps ``first`` … ``first + n - 1``."""
    start = -(-first // period) * period
    return np.arange(start, first + n, period)


def perception_state(seed: int) -> np.ndarray:
    """The perception generators of run ``seed`` (module docstring, Randomness).

    Returns (2, 4) uint64: the xoshiro256** states of the noise and of the miss
    generator, from the two children of ``np.random.SeedSequence([seed, 1])``.
    """
    noise, miss = np.random.SeedSequence([seed, 1]).spawn(2)
    return np.stack([noise.generate_state(4, np.uint64), miss.generate_state(4, np.uint64)])


def draw_camera(
    state: np.ndarray,
    settings: PerceptionSettings,
    n_refreshes: int,
    n_robots: int,
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The draws of ``n_refreshes`` camera updates of one run, as the kernel makes them.

    state : (2, 4) uint64 (:func:`perception_state`), advanced in place.
    Returns noise (R, N, 2), standard normals (zeros when σ_p = 0), and uniforms
    (R, N) in [0, 1) (zeros when the miss probability is 0), R = ``n_refreshes``;
    into the leading R rows of ``out`` if given.
    """
    if out is None:
        out = (np.zeros((n_refreshes, n_robots, 2)), np.zeros((n_refreshes, n_robots)))
    noise, uniforms = out[0][:n_refreshes], out[1][:n_refreshes]
    z, u = np.zeros((n_refreshes * n_robots, 2)), np.zeros(n_refreshes * n_robots)
    # numba only here: the bridge and the launcher import this module for the settings
    # and would otherwise load numba (0.15-0.3 s) at every start, a restart's included
    from aes_ros.xoshiro import camera_draws

    camera_draws(state, settings.sigma > 0.0, settings.miss > 0.0, z, u)
    noise[...], uniforms[...] = z.reshape(noise.shape), u.reshape(uniforms.shape)
    return noise, uniforms


def missed_robots(uniforms: np.ndarray, miss: float, step: int) -> np.ndarray:
    """Robots the camera misses at refresh ``step``: ``uniforms < miss``, none at step 0.

    uniforms : (..., N) in [0, 1). Returns (..., N) bool.
    """
    if step == 0:
        return np.zeros(uniforms.shape, dtype=bool)
    return uniforms < miss


def perceived_frame(
    delayed_positions: np.ndarray,
    delayed_headings: np.ndarray,
    held_positions: np.ndarray,
    held_headings: np.ndarray,
    noise: np.ndarray,
    missed: np.ndarray,
    sigma: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The perceived frame after a camera update.

    P̃_i = x_i(t − D) + σ_p z_i and Θ̃_i = θ_i(t − D) for a robot seen, the held
    P̃_i, Θ̃_i for a robot missed.

    Parameters
    ----------
    delayed_positions : (..., N, 2) [m] and delayed_headings : (..., N) [rad], the
        true state D steps ago (see :func:`delay_steps`).
    held_positions : (..., N, 2) [m] and held_headings : (..., N) [rad], the frame
        shown until now.
    noise : (..., N, 2) standard normals z. missed : (..., N) bool.
    sigma : σ_p [m].

    Returns
    -------
    positions : (..., N, 2) [m]; headings : (..., N) [rad].
    """
    seen = delayed_positions + sigma * noise
    return (
        np.where(missed[..., None], held_positions, seen),
        np.where(missed, held_headings, delayed_headings),
    )


class PerceptionStream:
    """The perceived frame of ONE run of N robots, fed the true state a step at a time.

    For a node that produces the poses the robots see (e.g. ``/swarm/poses`` of a
    simulated tracker); it draws what run ``seed`` of the offline simulator draws,
    so it gives that run's frames for the same true states.

    Parameters
    ----------
    settings : σ_p, τ, f_cam, miss probability.
    n_robots : N.
    dt : control step Δt [s]: :meth:`see` is called once per step.
    seed : the run's seed (its generators: :func:`perception_state`).
    """

    def __init__(
        self,
        settings: PerceptionSettings,
        n_robots: int,
        dt: float,
        seed: int,
    ) -> None:
        self.settings, self.n_robots = settings, n_robots
        self.period = camera_period_steps(settings.rate, dt)
        self.delay = delay_steps(settings.delay, dt)
        self._state = perception_state(seed)
        self._history: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=self.delay + 1)
        self._next_step = 0
        self._positions = np.zeros((n_robots, 2))
        self._headings = np.zeros(n_robots)

    def see(
        self, positions: np.ndarray, headings: np.ndarray, step: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """The perceived frame at ``step`` given the true state at that step.

        positions : (N, 2) [m], headings : (N,) [rad], the true state before step
        ``step``; steps must come in order 0, 1, 2, … (the delay keeps a history).
        Returns perceived positions (N, 2) [m] and headings (N,) [rad] (copies).
        """
        if step != self._next_step:
            raise ValueError(f"step: expected {self._next_step} (steps in order), got {step}")
        state = (
            np.array(positions, dtype=float).reshape(self.n_robots, 2),
            np.array(headings, dtype=float).reshape(self.n_robots),
        )
        if step == 0:
            self._history.extend([state] * (self.delay + 1))
        else:
            self._history.append(state)
        if step % self.period == 0:
            noise, uniforms = draw_camera(self._state, self.settings, 1, self.n_robots)
            delayed_positions, delayed_headings = self._history[0]
            self._positions, self._headings = perceived_frame(
                delayed_positions,
                delayed_headings,
                self._positions,
                self._headings,
                noise[0],
                missed_robots(uniforms[0], self.settings.miss, step),
                self.settings.sigma,
            )
        self._next_step += 1
        return self._positions.copy(), self._headings.copy()
