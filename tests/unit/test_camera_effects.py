"""The simulated camera's realism options (sim_bridge.camera_effects): each changes the
frame as a real camera would, and the tracker still finds every robot with the
``realistic`` preset."""

from __future__ import annotations

import numpy as np
import pytest
from test_tracker_core import setup, true_calibration

from aes_ros.markers import scattered_robots
from aes_ros.tracking.detection import detect_markers
from aes_ros.tracking.pose import marker_poses
from sim_bridge import camera_effects as fx


def test_off_by_default_leaves_the_frame_as_rendered() -> None:
    frame = np.random.default_rng(0).integers(0, 256, (48, 64), dtype=np.uint8)
    out = fx.apply(frame, fx.Effects(), None, np.random.default_rng(1))
    np.testing.assert_array_equal(out, frame)


def test_uneven_lighting_darkens_corners_and_the_right_edge() -> None:
    gain = fx.lighting_gain((480, 640), vignetting=0.3, gradient=0.0)
    assert gain[240, 320] == pytest.approx(1.0, abs=1e-3)
    assert gain[0, 0] == pytest.approx(0.7, abs=1e-3) and gain[-1, -1] == pytest.approx(0.7)
    ramp = fx.lighting_gain((480, 640), vignetting=0.0, gradient=0.15)
    assert ramp[100, 0] == pytest.approx(1.0) and ramp[100, -1] == pytest.approx(0.85)
    white = np.full((480, 640), 200, np.uint8)
    out = fx.apply(white, fx.Effects(vignetting=0.3), gain, np.random.default_rng(0))
    assert out[240, 320] == 200 and out[0, 0] == 140


@pytest.mark.parametrize("grey", [20.0, 200.0])
def test_sensor_noise_has_the_shot_and_read_variance(grey: float) -> None:
    full_well, read = 10_000.0, 6.0
    flat = np.full((400, 400), grey, np.float32)
    out = fx.sensor_noise(flat, full_well, read, np.random.default_rng(0)).astype(float)
    scale = full_well / 255.0  # electrons per grey level
    expected = (grey * scale + read**2) / scale**2 + 1 / 12  # + rounding to levels
    assert out.mean() == pytest.approx(grey, abs=0.05)
    assert out.var() == pytest.approx(expected, rel=0.05)
    assert fx.sensor_noise(flat, full_well, 0.0, np.random.default_rng(0)).var() < out.var()


def test_motion_blur_smears_a_moving_robot_along_its_motion_only() -> None:
    _, renderer = setup((1.0, 0.8), 640, 480, noise_sigma=0.0, blur_sigma=0.0)
    positions = np.array([[-0.2, 0.0], [0.2, 0.0]])
    headings = np.zeros(2)
    velocity = np.array([[0.0, 0.0], [0.5, 0.0]])  # robot 1 runs east at 0.5 m/s
    sharp = renderer.render(positions, headings).astype(np.float32)
    smeared = fx.exposed(renderer.render, positions, headings, velocity, np.zeros(2), 0.02, 5)
    changed = np.abs(smeared - sharp) > 1.0
    cols = np.flatnonzero(changed.any(axis=0))
    assert cols.size and cols.min() > 320  # the still robot (west half) is untouched
    # the smear is long in x (1 cm over the exposure) and keeps the rows of the body
    rows = np.flatnonzero(changed.any(axis=1))
    moving = sharp[:, 320:] != sharp[0, -1]
    body_rows = np.flatnonzero(moving.any(axis=1))
    assert rows.min() >= body_rows.min() - 1 and rows.max() <= body_rows.max() + 1
    # intermediate grey levels: edges become ramps, not steps
    assert np.count_nonzero((smeared % 1.0) > 0.0) > 0


@pytest.mark.parametrize(
    ("n", "arena", "size", "position_mm"),
    [(25, (2.0, 1.5), (1280, 960), 2.0), (100, (4.0, 3.0), (2048, 1536), 3.0)],
)
def test_the_tracker_finds_every_robot_with_the_realistic_preset(n, arena, size, position_mm):
    """Robots at 0.07 m/s rms and 1 rad/s rms (faster than a Mona): every one found, and
    within ``position_mm`` of its pose at the exposure's end (measured: 0.4 mm rms,
    1.5 mm worst over 10 frames of each size)."""
    cam, renderer = setup(arena, *size)
    calibration = true_calibration(cam)
    preset = fx.REALISTIC
    gain = fx.lighting_gain(size[::-1], preset.vignetting, preset.gradient)
    rng = np.random.default_rng(3)
    errors = []
    for _ in range(2):
        positions, headings = scattered_robots(n, arena, rng)
        velocity, yaw_rate = rng.normal(0.0, 0.07, (n, 2)), rng.normal(0.0, 1.0, n)
        frame = fx.exposed(renderer.render, positions, headings, velocity, yaw_rate,
                           preset.exposure_s, preset.blur_samples)  # fmt: skip
        found = detect_markers(fx.apply(frame, preset, gain, rng))
        assert found.ids.tolist() == list(range(n))
        p, _, _ = marker_poses(found.ids, found.corners, calibration)
        errors.append(np.linalg.norm(p - positions, axis=1))
    assert 1e3 * np.concatenate(errors).max() <= position_mm


@pytest.mark.parametrize(
    ("field", "value"), [("exposure_s", -0.1), ("vignetting", 1.0), ("read_noise", -1.0)]
)
def test_an_option_out_of_range_is_named(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        fx.Effects(**{field: value})
