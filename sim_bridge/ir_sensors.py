"""The Mona's IR proximity sensors in the bridge: rays in pybullet, published as a driver does.

:func:`cast_ir` casts every robot's five rays (:data:`aes_ros.ir.IR_ANGLES`) in one
``pybullet.rayTestBatch`` call (up to 1638 robots) against whatever the world's bodies are
(robots, and walls or obstacles the world holds); :class:`IrSensors` turns them into
readings with the response of :func:`aes_ros.ir_readings.ir_response` and publishes them on
``/mona_<i>/ir_<k>`` (sensor_msgs/Range, frame ``mona_<i>/ir_<k>``, stamped with sim time),
the topics and type of the Mona driver, at ``ir_rate`` per second of sim time.
docs/model.md, "IR proximity sensors".
"""

from __future__ import annotations

import math
import struct
import time

import numpy as np
import pybullet as pb
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Range

from aes_ros.frames import yaw_from_quaternion
from aes_ros.ir import IR_ANGLES
from aes_ros.ir_readings import ir_response
from aes_ros.mona.sensors import IR_FIELD_OF_VIEW, IrModel
from aes_ros.params import ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.qos import SENSOR
from sim_bridge.world import _WHEEL, World

#: Rays hit every collision group but the wheels' and caster's, which the kernel's
#: body discs do not have either.
RAY_MASK = 0xFFFF & ~_WHEEL
#: Rays per rayTestBatch call: pybullet refuses more than 16384 and answers only 16383
#: of exactly 16384.
MAX_RAYS = 8192
#: How often [s of wall time] the bridge checks which robots' IR topics have subscribers.
LISTENERS_EVERY = 0.25
#: The IR model's parameters, as the Mona driver names them.
MODEL_PARAMETERS = ("ir_gain", "ir_offset", "ir_min_range", "ir_max_range", "ir_falling")


def cast_ir(world: World, max_range: float, robots: np.ndarray | None = None) -> np.ndarray:
    """Distance [m] from each sensor on the body's rim to the first body its ray meets, (n, 5).

    ``robots`` : indices of the robots to cast for (None = all). A sensor that meets nothing
    within ``max_range`` reads ``max_range``; one pressed into a body reads 0. Each ray
    starts at the body's centre, inside its own body, which Bullet's ray test does not
    report, so a robot never sees itself. One ``rayTestBatch`` call per :data:`MAX_RAYS`
    rays.
    """
    # The bodies' pybullet poses, placed first if the kinematic world has moved them.
    centres, quats = world._base_states()
    if robots is not None:
        centres, quats = centres[robots], quats[robots]
    angle = yaw_from_quaternion(quats)[:, None] + IR_ANGLES  # (n, 5)
    radius = world.geometry.body_radius
    length = radius + max_range
    start = np.repeat(centres, len(IR_ANGLES), axis=0)
    end = start.copy()
    end[:, 0] += length * np.cos(angle).ravel()
    end[:, 1] += length * np.sin(angle).ravel()
    hits = []
    for first in range(0, len(start), MAX_RAYS):
        hits += pb.rayTestBatch(
            start[first : first + MAX_RAYS].tolist(),
            end[first : first + MAX_RAYS].tolist(),
            collisionFilterMask=RAY_MASK,
            physicsClientId=world._client,
        )
    fraction = np.array([1.0 if hit[0] < 0 else hit[2] for hit in hits])
    return np.clip(fraction * length - radius, 0.0, max_range).reshape(-1, len(IR_ANGLES))


def _serialised_range(frame_id: str) -> bytearray:
    """A sensor_msgs/Range of an IR sensor in ``frame_id``, serialised (CDR)."""
    msg = Range(radiation_type=Range.INFRARED, field_of_view=IR_FIELD_OF_VIEW)
    msg.header.frame_id = frame_id
    return bytearray(serialize_message(msg))


def declare_ir_parameters(node: Node, rate: float = 20.0) -> None:
    """Declare the bridge's ``ir_*`` parameters (the IR model's as the Mona driver's);
    ``ir_rate`` defaults to ``rate``, the scenario's ``ir_rate``."""
    fd = rp.float_descriptor
    node.declare_parameter(
        "ir_rate",
        rate,
        fd(
            "IR readings per sensor per second of sim time (at most publish_rate); 0 = off",
            "Hz",
            0.0,
            1000.0,
        ),
    )
    node.declare_parameter(
        "ir_noise", 0.0, fd("IR: standard deviation of the noise on a distance", "m", 0.0, 1.0)
    )
    node.declare_parameter(
        "ir_quantise",
        True,
        rp.bool_descriptor("IR: pass each reading through a whole raw ADC count of the IR model"),
    )
    model = IrModel()
    node.declare_parameter(
        "ir_gain", model.gain, fd("IR: range = gain / (raw - offset)", "m", 1e-6, 1e6)
    )
    node.declare_parameter(
        "ir_offset", model.offset, fd("IR: ambient reading", "ADC counts", -1e5, 1e5)
    )
    node.declare_parameter("ir_min_range", model.min_range, fd("IR: nearest range", "m", 0.0, 10.0))
    node.declare_parameter(
        "ir_max_range", model.max_range, fd("IR: farthest range", "m", 1e-3, 10.0)
    )
    node.declare_parameter(
        "ir_falling",
        model.falling,
        rp.bool_descriptor("IR: the reading falls as an obstacle comes closer"),
    )


class IrSensors:
    """Every robot's five IR readings of a bridge's world, published at ``ir_rate``.

    Parameters (ROS, declared by :func:`declare_ir_parameters`)
    ----------------------------------------------------------
    ir_rate : float [Hz], default the scenario's ``ir_rate`` (20)
        Readings per sensor per second of sim time; 0 = off. A robot's five rays are cast
        and published only while one of its ``ir_<k>`` topics has a subscriber.
    ir_noise : float [m], default 0.0
        Standard deviation of Gaussian noise on each distance (seeded by ``seed``).
    ir_quantise : bool, default true
        Pass each reading through a whole raw ADC count of the IR model.
    ir_gain, ir_offset, ir_min_range, ir_max_range, ir_falling
        The IR model, as the Mona driver's parameters (:class:`aes_ros.mona.sensors.IrModel`).
    """

    def __init__(self, node: Node, world: World, seed: int) -> None:
        self.node, self.world = node, world
        self.rng = np.random.default_rng([seed, 0x1F])  # apart from other draws of the seed
        get = node.get_parameter
        self.rate = get("ir_rate").value
        self.noise = get("ir_noise").value
        self.quantise = get("ir_quantise").value
        self.model = self._model({})
        reason = self.model.check()
        if reason is not None:
            raise ParameterError(reason)
        self.pubs: list[list] = []
        self.messages: list[list[bytearray]] = []
        self.listened = np.zeros(0, dtype=int)
        self.checked = -math.inf
        self.next_time = world.time
        if self.rate > 0.0:
            self._create_publishers()
        node.add_on_set_parameters_callback(self.on_set_parameters)
        node.add_post_set_parameters_callback(self.on_parameters_set)

    def _model(self, changed: dict) -> IrModel:
        def value(name: str):
            return changed.get(name, self.node.get_parameter(name).value)

        return IrModel(*(value(name) for name in MODEL_PARAMETERS))

    def on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Refuse IR model constants that cannot work (the old ones are kept)."""
        changed = {p.name: p.value for p in params if p.name in MODEL_PARAMETERS}
        reason = self._model(changed).check() if changed else None
        return SetParametersResult(successful=reason is None, reason=reason or "")

    def on_parameters_set(self, params: list[Parameter]) -> None:
        """Apply changed ``ir_*`` parameters."""
        names_set = {p.name for p in params}
        if "ir_rate" in names_set:
            self.rate = self.node.get_parameter("ir_rate").value
            self.next_time = self.world.time
        self.noise = self.node.get_parameter("ir_noise").value
        self.quantise = self.node.get_parameter("ir_quantise").value
        if names_set & set(MODEL_PARAMETERS):
            self.model = self._model({})

    def _create_publishers(self) -> None:
        """The 5 N publishers and their messages, made when IR is first on.

        Each message is kept serialised (publishers take serialised messages) and only its
        stamp and numbers are written into it: no Python message per reading.
        """
        count = len(IR_ANGLES)
        for i in range(self.world.n):
            topics = [names.robot_topic(i, f"{names.IR}_{k}") for k in range(count)]
            self.pubs.append([self.node.create_publisher(Range, t, SENSOR) for t in topics])
            self.messages.append(
                [_serialised_range(f"mona_{i}/{names.IR}_{k}") for k in range(count)]
            )

    def _update_listeners(self) -> None:
        now = time.monotonic()
        if now - self.checked >= LISTENERS_EVERY:
            self.checked = now
            self.listened = np.array(
                [
                    i
                    for i, pubs in enumerate(self.pubs)
                    if any(pub.get_subscription_count() for pub in pubs)
                ],
                dtype=int,
            )

    def publish(self, stamp) -> None:
        """Publish the readings if one is due at the world's sim time (``stamp``)."""
        if self.rate <= 0.0 or self.world.time < self.next_time - 1e-9:
            return
        self.next_time += 1.0 / self.rate
        if self.next_time <= self.world.time:  # behind (a rate above publish_rate)
            self.next_time = self.world.time + 1.0 / self.rate
        if not self.pubs:
            self._create_publishers()
        self._update_listeners()
        if not len(self.listened):
            return
        model = self.model
        distances = cast_ir(self.world, model.max_range, self.listened)
        readings = np.empty_like(distances)
        normals = (
            self.rng.standard_normal(distances.shape)
            if self.noise > 0.0
            else np.zeros(distances.shape)
        )
        ir_response(
            distances,
            normals,
            self.noise,
            model.gain,
            model.offset,
            model.min_range,
            model.max_range,
            model.falling,
            self.quantise,
            readings,
        )
        variance = self.noise**2
        for i, row in zip(self.listened.tolist(), readings.tolist(), strict=True):
            for pub, data, r in zip(self.pubs[i], self.messages[i], row, strict=True):
                # CDR: the stamp follows the 4-byte encapsulation header; the message ends
                # in min_range, max_range, range, variance (float32)
                struct.pack_into("<iI", data, 4, stamp.sec, stamp.nanosec)
                struct.pack_into(
                    "<4f", data, len(data) - 16, model.min_range, model.max_range, r, variance
                )
                pub.publish(bytes(data))
