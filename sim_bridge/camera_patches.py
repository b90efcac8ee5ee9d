"""The pre-rendered patches the simulated overhead camera (:mod:`sim_bridge.camera_render`)
warps into its frames: a robot's top (dark body disc, round white sticker, marker) and a
reference marker, supersampled, area-downsampled and pre-filtered by a pixel's footprint,
stored as premultiplied grey and alpha."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from aes_ros.markers import DICTIONARY, RobotMarker, marker_image

#: Supersampling of the pre-rendered patches (their round edges are anti-aliased).
SUPERSAMPLE = 4
#: Transparent texels around a patch, room for the pre-filter to spread into.
PAD = 3
#: fillConvexPoly's fractional bits.
SHIFT = 4


@dataclass(frozen=True)
class Shades:
    """Grey levels (0-255) of what the camera sees."""

    floor: int = 128
    body: int = 45
    obstacle: int = 60
    white: int = 235
    black: int = 20


@dataclass(frozen=True)
class Patch:
    """A pre-rendered flat patch: premultiplied grey and alpha (0-255), (n, n, 2) uint8."""

    image: np.ndarray
    side: float  #: [m] covered by the patch's n texels


def _alpha_patch(value: np.ndarray, alpha: np.ndarray, side: float, blur: float) -> Patch:
    """A premultiplied uint8 patch from supersampled value and alpha (uint8).

    Area-downsampled by ``SUPERSAMPLE``, then blurred by ``blur`` [texels]: the
    footprint of an image pixel (a box of 1 px has the σ of a Gaussian of
    1/√12 px), so that sampling the patch at pixel centres integrates the scene
    over each pixel, as a sensor does.
    """
    n = value.shape[0] // SUPERSAMPLE
    a = alpha.astype(np.float32) / 255.0
    small_a = cv2.resize(a, (n, n), interpolation=cv2.INTER_AREA)
    small_v = cv2.resize(value.astype(np.float32) * a, (n, n), interpolation=cv2.INTER_AREA)
    image = np.stack([small_v, 255.0 * small_a], axis=-1)
    if blur > 0.0:
        image = cv2.GaussianBlur(image, (0, 0), blur, borderType=cv2.BORDER_CONSTANT)
    return Patch(np.ascontiguousarray(np.clip(np.rint(image), 0, 255).astype(np.uint8)), side)


def _marker_hi(marker_id: int, cell_hi: int, shades: Shades, dictionary_id: int) -> np.ndarray:
    """The marker at ``cell_hi`` supersampled pixels per cell, in the given shades."""
    img = marker_image(marker_id, cell_hi, dictionary_id)
    return np.where(img > 127, shades.white, shades.black).astype(np.uint8)


def robot_patch(
    marker_id: int,
    marker: RobotMarker,
    body_radius: float,
    texels_per_cell: int,
    texels_per_px: float = 1.0,
    shades: Shades = Shades(),
    dictionary_id: int = DICTIONARY,
) -> Patch:
    """The top of a robot as a patch: dark disc, round white sticker, marker.

    Centred on the marker; its columns run along the marker's x axis, its rows
    down the marker's y axis (the marker image as printed). ``texels_per_px``
    sets the pixel-footprint pre-filter (see :func:`_alpha_patch`).
    """
    cells = marker_image(0, 1, dictionary_id).shape[0]
    cell = marker.size / cells
    texel = cell / texels_per_cell
    margin = math.ceil((body_radius - 0.5 * marker.size) / texel) + PAD
    n = cells * texels_per_cell + 2 * max(margin, 0)
    side = n * texel
    hi = n * SUPERSAMPLE
    scale = hi / side  # supersampled pixels per metre
    centre = 0.5 * hi - 0.5
    alpha = np.zeros((hi, hi), np.uint8)
    big = 1 << SHIFT
    cv2.circle(
        alpha,
        (round(centre * big), round(centre * big)),
        round(body_radius * scale * big),
        255,
        -1,
        cv2.LINE_AA,
        SHIFT,
    )
    value = np.full((hi, hi), shades.body, np.uint8)
    sticker = np.zeros((hi, hi), np.uint8)
    radius = min(0.5 * marker.sticker_diameter, body_radius)
    centre_big = round(centre * big)
    cv2.circle(
        sticker, (centre_big, centre_big), round(radius * scale * big), 255, -1, cv2.LINE_AA, SHIFT
    )
    value = (value * (1.0 - sticker / 255.0) + shades.white * (sticker / 255.0)).astype(np.uint8)
    m = _marker_hi(marker_id, texels_per_cell * SUPERSAMPLE, shades, dictionary_id)
    start = (hi - m.shape[0]) // 2
    value[start : start + m.shape[0], start : start + m.shape[0]] = m
    return _alpha_patch(value, alpha, side, texels_per_px / math.sqrt(12.0))


def reference_patch(
    marker_id: int,
    texels_per_cell: int,
    size: float,
    texels_per_px: float = 1.0,
    shades: Shades = Shades(),
    dictionary_id: int = DICTIONARY,
) -> Patch:
    """A reference marker as a patch: the black square with one white cell around it."""
    cells = marker_image(0, 1, dictionary_id).shape[0]
    cell_hi = texels_per_cell * SUPERSAMPLE
    m = _marker_hi(marker_id, cell_hi, shades, dictionary_id)
    value = cv2.copyMakeBorder(m, *(cell_hi,) * 4, cv2.BORDER_CONSTANT, value=shades.white)
    alpha = np.full_like(value, 255)
    pad = PAD * SUPERSAMPLE
    value = cv2.copyMakeBorder(value, *(pad,) * 4, cv2.BORDER_CONSTANT, value=0)
    alpha = cv2.copyMakeBorder(alpha, *(pad,) * 4, cv2.BORDER_CONSTANT, value=0)
    side = size / cells * (cells + 2 + 2 * PAD / texels_per_cell)
    return _alpha_patch(value, alpha, side, texels_per_px / math.sqrt(12.0))
