"""The bridge's simulated IR sensors seen by an rclpy client, as a Mona driver's would be
(real ``aes-sim-bridge`` process, own domain)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Range

from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.sensors import IR_FIELD_OF_VIEW, IrModel
from aes_ros.ros import interface as names
from aes_ros.ros.conversions import stamp_to_ns
from aes_ros.ros.qos import SENSOR
from aes_ros.world_state import WorldState

BRIDGE = "/" + names.SIM_BRIDGE_NODE
GAP = 0.05  #: between the rims of robots 0 and 1, facing each other [m]


def test_every_robot_reads_its_ir_sensors_and_a_robot_facing_another_sees_it(
    spawn, probe, tmp_path
):
    g = MonaGeometry()
    # robots 0 and 1 face each other GAP apart; robots 2 and 3 stand alone
    positions = np.array(
        [[0.0, 0.0], [GAP + 2 * g.body_radius + 2 * g.axle_offset, 0.0], [1.0, 1.0], [-1.0, 1.0]]
    )
    headings = np.array([0.0, math.pi, 0.3, -2.0])
    state = WorldState(0.0, positions, headings).save(tmp_path / "layout.npz")
    n = len(headings)
    readings = {
        (i, k): probe.record(Range, names.robot_topic(i, f"{names.IR}_{k}"), SENSOR)
        for i in range(n)
        for k in range(5)
    }
    spawn.start(
        "aes-sim-bridge",
        "--ros-args",
        "-p",
        "scenario:=linear",
        "-p",
        f"num_robots:={n}",
        "-p",
        f"resume_from:={state}",
        "-p",
        "lockstep_timeout:=0.2",
        name="sim_bridge",
    )
    probe.wait(
        lambda: all(len(r) >= 3 for r in readings.values()),
        30.0,
        "three readings of every robot's five IR sensors",
    )

    model = IrModel()
    for (i, k), msgs in readings.items():
        msg = msgs[-1]
        assert msg.header.frame_id == f"mona_{i}/ir_{k}"
        assert msg.radiation_type == Range.INFRARED
        assert msg.field_of_view == pytest.approx(IR_FIELD_OF_VIEW)
        assert (msg.min_range, msg.max_range) == pytest.approx((model.min_range, model.max_range))
        facing = i in (0, 1) and k == 0
        # a count of the IR model is 0.25 mm wide at 5 cm
        assert msg.range == pytest.approx(GAP if facing else model.max_range, abs=0.0005)
        # 10 readings per second of sim time (the default ir_rate), stamped with it
        stamps = [stamp_to_ns(m.header.stamp) for m in msgs[-3:]]
        assert np.diff(stamps) == pytest.approx([1e8, 1e8], abs=1e3)

    # IR model constants that cannot work are refused with the reason; the old ones stay
    (result,) = probe.set_parameters(BRIDGE, [Parameter("ir_max_range", value=0.005)])
    assert not result.successful and "min_range < max_range" in result.reason
    assert probe.get_parameters(BRIDGE, ["ir_max_range"]) == [model.max_range]
    assert "Traceback" not in spawn.logs()
