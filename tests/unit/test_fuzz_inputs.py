"""Fuzzing the hand-written parsers of untrusted input: whatever arrives, only the
documented error comes out.

- a viewer's control message (:func:`dashboard_node.controls.parse_control`): any JSON
  value, and any text, gives a ``Control`` or a ``ControlError``;
- a parameter value from a scenario file, ``--set`` or a ROS parameter
  (:meth:`aes_ros.param_spec.ParamSpec.validate`): any value gives the value converted or a
  ``ParameterError`` naming the parameter;
- every wire-format decoder of :mod:`aes_ros.ros.cdr`: valid messages with bits flipped,
  bytes cut, inserted or overwritten by a huge length give a correct decode or a
  ``BadMessageError``, never another exception or an allocation sized by a lying field.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from aes_ros.param_spec import ParameterError
from aes_ros.params import PARAMS
from aes_ros.ros.cdr import (
    OdometryEncoder,
    PoseArrayEncoder,
    decode_image,
    decode_odometry,
    decode_pose_array,
    decode_stamp,
    decode_twist,
    encode_image,
    encode_twist,
)
from aes_ros.ros.conversions import BadMessageError
from dashboard_node.controls import (
    MAX_MESSAGE_BYTES,
    ControlError,
    Drive,
    Enable,
    SetGain,
    SimAction,
    parse_control,
)
from dashboard_node.view import GAIN_NAMES

FUZZ = settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# --- control messages -------------------------------------------------------------------

KEYS = ["type", "direction", "omega", "enabled", "name", "value", "action"]
WORDS = ["drive", "enable", "gain", "sim", "pause", "resume", "reset", *GAIN_NAMES, ""]
numbers = st.one_of(
    st.integers(),
    st.integers(min_value=10**300, max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, -1, 0.5, -0.7, 2**63, -(2**64), 1e308, 5e-324]),
)
scalars = st.one_of(st.none(), st.booleans(), numbers, st.sampled_from(WORDS), st.text(max_size=8))
json_values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.sampled_from(KEYS) | st.text(max_size=4), inner, max_size=5),
    ),
    max_leaves=20,
)
#: Objects shaped like control messages: the real type and keys, random values.
controls = st.fixed_dictionaries(
    {"type": st.sampled_from(["drive", "enable", "gain", "sim"]) | json_values},
    optional={key: json_values for key in KEYS[1:]},
)


def only_a_control_or_its_error(text: str | bytes) -> None:
    try:
        control = parse_control(text)
    except ControlError as exc:
        assert str(exc) and len(str(exc)) < 400  # a reason to read, not an echo
        return
    assert isinstance(control, Drive | Enable | SetGain | SimAction)
    numbers_in = [*(control.direction or ())] if isinstance(control, Drive) else []
    numbers_in += [getattr(control, name, None) for name in ("omega", "value")]
    assert all(math.isfinite(v) for v in numbers_in if v is not None)


@FUZZ
@given(message=controls | json_values)
@example(message={"type": "sim", "action": "pause"})  # valid, and has no number field
@example(message={"type": "enable", "enabled": True})
def test_any_json_gives_a_control_or_a_control_error(message: Any) -> None:
    # NaN and infinity as Python's json writes them (not JSON), which a page could send
    only_a_control_or_its_error(json.dumps(message))


@FUZZ
@given(text=st.text(max_size=64) | st.binary(max_size=64))
def test_any_text_or_bytes_gives_a_control_or_a_control_error(text: str | bytes) -> None:
    only_a_control_or_its_error(text)


@pytest.mark.parametrize(
    "text",
    [
        '{"type": []}',
        '{"type": {}}',
        '{"type": "gain", "name": "alpha", "value": ' + "9" * 400 + "}",
        '{"type": "drive", "direction": [' + "9" * 400 + ", 0]}",
        '{"type": "drive", "omega": -' + "9" * 400 + "}",
        '{"type": "gain", "name": ["alpha"], "value": 1}',
        '{"type": "sim", "action": {"reset": 1}}',
        '{"type": "drive", "omega": ' + "9" * 5000 + "}",
        "[" * 3000 + "]" * 3000,
        '"' + "\\ud800" * 10 + '"',
        "é" * (MAX_MESSAGE_BYTES // 2 + 1),
    ],
)
def test_messages_that_raised_other_errors_are_control_errors(text: str) -> None:
    with pytest.raises(ControlError):
        parse_control(text)


# --- parameter values -------------------------------------------------------------------


@FUZZ
@given(
    name=st.sampled_from(list(PARAMS)),
    value=json_values | st.text(max_size=12) | st.builds(str, numbers) | st.tuples(numbers),
)
def test_any_parameter_value_is_converted_or_refused_naming_the_parameter(
    name: str, value: Any
) -> None:
    try:
        PARAMS[name].validate(value)
    except ParameterError as exc:
        assert str(exc).startswith(f"{name}: ") and len(str(exc)) < 400, str(exc)


# --- wire-format decoders ---------------------------------------------------------------


def pose_array() -> bytes:
    rng = np.random.default_rng(1)
    return PoseArrayEncoder(3, "odom").encode(5, 6, rng.normal(size=(3, 2)), rng.normal(size=3))


def odometry() -> bytes:
    return OdometryEncoder("odom", "mona_0/base_link").encode(1, 2, 0.5, -0.2, 0.6, 0.8, 0.05, 0, 1)


def image() -> bytes:
    return encode_image(1, 2, "camera", np.arange(24, dtype=np.uint8).reshape(2, 4, 3), "rgb8")


#: Each decoder with a valid message of its type.
DECODERS: dict[str, tuple[Callable[[bytes], Any], Callable[[], bytes]]] = {
    "pose_array": (decode_pose_array, pose_array),
    "pose_array_in_odom": (lambda data: decode_pose_array(data, frame_id="odom"), pose_array),
    "stamp": (decode_stamp, pose_array),
    "odometry": (decode_odometry, odometry),
    "twist": (decode_twist, lambda: encode_twist(0.05, -0.3)),
    "image": (decode_image, image),
}


@st.composite
def mutated(draw: st.DrawFn, data: bytes) -> bytes:
    """``data`` with a few bits flipped, bytes cut, inserted, or a uint32 overwritten by
    a huge (or off-by-a-little) count: the fields a decoder trusts."""
    buf = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "cut", "insert", "length", "tail"]))
        if kind == "flip" and buf:
            at = draw(st.integers(0, len(buf) - 1))
            buf[at] ^= 1 << draw(st.integers(0, 7))
        elif kind == "cut":
            at = draw(st.integers(0, len(buf)))
            buf = buf[:at] + buf[at + draw(st.integers(1, 16)) :]
        elif kind == "insert":
            at = draw(st.integers(0, len(buf)))
            buf[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif kind == "length" and len(buf) >= 4:
            at = draw(st.integers(0, (len(buf) - 4) // 4)) * 4
            value = draw(st.sampled_from([2**32 - 1, 2**31, 2**28, 0, 1]) | st.integers(0, 64))
            struct.pack_into("<I", buf, at, value)
        elif kind == "tail":
            buf = buf[: draw(st.integers(0, len(buf)))]
    return bytes(buf)


@pytest.mark.parametrize("name", DECODERS)
@FUZZ
@given(data=st.data())
def test_mutated_messages_decode_or_raise_bad_message(name: str, data: st.DataObject) -> None:
    decode, valid = DECODERS[name]
    message = data.draw(mutated(valid()))
    try:
        decoded = decode(message)
    except BadMessageError as exc:
        assert str(exc)
        return
    assert isinstance(decoded, tuple)


@pytest.mark.parametrize("name", DECODERS)
@FUZZ
@given(garbage=st.binary(max_size=200))
def test_garbage_decodes_or_raises_bad_message(name: str, garbage: bytes) -> None:
    decode, _ = DECODERS[name]
    try:
        decode(garbage)
    except BadMessageError:
        pass


@pytest.mark.parametrize("name", DECODERS)
def test_valid_messages_still_decode(name: str) -> None:
    """The fuzz above is not vacuous: the unmutated messages decode."""
    decode, valid = DECODERS[name]
    assert isinstance(decode(valid()), tuple)


def test_a_lying_pose_count_is_refused_without_allocating_it() -> None:
    data = bytearray(pose_array())
    count_at = 4 + 12 + len(b"odom\0")  # after the header: the pose count
    count_at += -count_at % 4
    struct.pack_into("<I", data, count_at, 2**32 - 1)
    with pytest.raises(BadMessageError, match="too short"):
        decode_pose_array(bytes(data))
