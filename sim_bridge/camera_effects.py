"""What a real camera adds to the simulated one's frames: motion blur over the exposure,
uneven lighting (vignetting and a gradient across the picture), and sensor noise (shot
noise of the collected electrons and read noise). Pure functions on ``uint8`` frames;
:class:`Effects` holds the options, all off by default (no cost), :data:`REALISTIC` a
preset of a typical USB camera under lab lights."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Effects:
    """exposure_s [s] (0: no motion blur), vignetting [gain lost at the corners, 0–1],
    gradient [gain lost from the left to the right edge, 0–1], full_well [electrons at
    white; 0: no shot noise], read_noise [electrons rms], blur_samples (renders a frame
    averages over its exposure)."""

    exposure_s: float = 0.0
    vignetting: float = 0.0
    gradient: float = 0.0
    full_well: float = 0.0
    read_noise: float = 0.0
    blur_samples: int = 5

    def __post_init__(self) -> None:
        checks = {
            "exposure_s": 0.0 <= self.exposure_s <= 1.0,
            "vignetting": 0.0 <= self.vignetting < 1.0,
            "gradient": 0.0 <= self.gradient < 1.0,
            "full_well": self.full_well >= 0.0,
            "read_noise": self.read_noise >= 0.0,
            "blur_samples": self.blur_samples >= 2,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"{name}: {getattr(self, name)} is out of range")

    @property
    def lighting(self) -> bool:
        return self.vignetting > 0.0 or self.gradient > 0.0

    @property
    def noise(self) -> bool:
        return self.full_well > 0.0 or self.read_noise > 0.0


#: 8 ms exposure, 30 % darker corners, 15 % darker right edge, a 10 000 e⁻ well, 6 e⁻ read.
REALISTIC = Effects(exposure_s=0.008, vignetting=0.3, gradient=0.15, full_well=10_000.0,
                    read_noise=6.0)  # fmt: skip


def lighting_gain(shape: tuple[int, int], vignetting: float, gradient: float) -> np.ndarray:
    """Gain ``(H, W)`` float32: ``1 − vignetting · r²`` (r = 1 at the corners, the
    cos⁴ fall-off to second order) times ``1 − gradient · x`` (x = 0 left, 1 right)."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (
        ((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2
    )
    return ((1.0 - vignetting * r2) * (1.0 - gradient * x / max(w - 1, 1))).astype(np.float32)


def sensor_noise(
    frame: np.ndarray, full_well: float, read_noise: float, rng: np.random.Generator
) -> np.ndarray:
    """``frame`` (grey levels, float) with shot noise (255 grey levels = ``full_well``
    e⁻) and read noise [e⁻ rms], as uint8. Shot noise is drawn as its normal limit
    (variance = the electrons), one draw for both: above ~10 e⁻ a Poisson draw differs
    by less than a grey level, and costs ~5× more."""
    scale = full_well / 255.0 if full_well > 0.0 else 1.0
    electrons = np.clip(frame, 0.0, None, dtype=np.float32) * np.float32(scale)
    variance = electrons if full_well > 0.0 else np.zeros_like(electrons)
    sigma = np.sqrt(variance + np.float32(read_noise**2))
    electrons += sigma * rng.standard_normal(frame.shape, dtype=np.float32)
    return np.clip(np.rint(electrons / np.float32(scale)), 0, 255).astype(np.uint8)


def exposed(
    render: Callable[[np.ndarray, np.ndarray], np.ndarray],
    positions: np.ndarray,
    headings: np.ndarray,
    velocity: np.ndarray,
    yaw_rate: np.ndarray,
    exposure_s: float,
    samples: int,
) -> np.ndarray:
    """The mean of ``samples`` renders over the exposure ending at the pose given:
    ``positions: (N, 2) [m]``, ``headings: (N,) [rad]``, ``velocity: (N, 2) [m/s]``,
    ``yaw_rate: (N,) [rad/s]``; float32 grey levels."""
    acc = None
    for t in np.linspace(-exposure_s, 0.0, samples):
        frame = render(positions + velocity * t, headings + yaw_rate * t)
        acc = frame.astype(np.float32) if acc is None else np.add(acc, frame, out=acc)
    return acc * np.float32(1.0 / samples)


def apply(
    frame: np.ndarray, effects: Effects, gain: np.ndarray | None, rng: np.random.Generator
) -> np.ndarray:
    """Uneven lighting (``gain`` from :func:`lighting_gain`) then sensor noise on
    ``frame``; uint8."""
    out = frame.astype(np.float32) if gain is None else np.multiply(frame, gain, dtype=np.float32)
    if effects.noise:
        return sensor_noise(out, effects.full_well, effects.read_noise, rng)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
