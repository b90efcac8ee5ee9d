"""The bridge's simulated IR sensors seen by an rclpy client, as a Mona driver's would be
(real ``aes-sim-bridge`` process, own domain)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Range

import aes_ros
from aes_ros.ir_readings import IrResponse, ir_ranges
from aes_ros.mona.geometry import MonaGeometry
from aes_ros.mona.sensors import IR_FIELD_OF_VIEW, IrModel
from aes_ros.params import PARAMS
from aes_ros.ros import interface as names
from aes_ros.ros.conversions import stamp_to_ns
from aes_ros.ros.qos import SENSOR
from aes_ros.world_state import WorldState

BRIDGE = "/" + names.SIM_BRIDGE_NODE
G = MonaGeometry()
#: From the pose point to sensor 0 [m].
FRONT = G.axle_offset + G.body_radius
GAP = 0.05  #: between the rims of robots 0 and 1, facing each other [m]
WALLS = [-2.0, 2.0, -2.0, 2.0]
CIRCLE = [-1.0 - FRONT - 0.07 - 0.05, 1.0, 0.05]  #: 0.07 m ahead of robot 3's sensor 0
BOX = [0.4, 0.6, -1.5, -1.0 - FRONT - 0.04]  #: 0.04 m ahead of robot 4's sensor 0
#: The scenario's ir_rate [Hz], half its default (a Mona's TELEMETRY rate, 20 Hz).
IR_RATE = PARAMS["ir_rate"].default / 2


def test_every_robot_reads_its_ir_sensors_and_sees_robots_walls_and_obstacles(
    spawn, probe, tmp_path
):
    # robots 0 and 1 face each other GAP apart; robot 2 faces the east wall 0.06 m away,
    # robot 3 a circle 0.07 m away, robot 4 a box 0.04 m away
    positions = np.array(
        [
            [0.0, 0.0],
            [GAP + 2 * FRONT, 0.0],
            [2.0 - FRONT - 0.06, 1.0],
            [-1.0, 1.0],
            [0.5, -1.0],
        ]
    )
    headings = np.array([0.0, math.pi, 0.0, math.pi, -math.pi / 2])
    state = WorldState(0.0, positions, headings).save(tmp_path / "layout.npz")
    scenario = tmp_path / "arena.yaml"
    scenario.write_text(
        (Path(aes_ros.__file__).parent / "scenarios" / "linear.yaml").read_text()
        + f"walls: {WALLS}\nobstacles:\n  - circle: {CIRCLE}\n  - box: {BOX}\n"
        + f"ir_rate: {IR_RATE}\n"
    )
    n = len(headings)
    readings = {
        (i, k): probe.record(Range, names.robot_topic(i, f"{names.IR}_{k}"), SENSOR)
        for i in range(n)
        for k in range(5)
    }
    params = [
        f"scenario:={scenario}",
        f"num_robots:={n}",
        f"resume_from:={state}",
        "lockstep_timeout:=0.2",
    ]
    spawn.start(
        "aes-sim-bridge", "--ros-args", *(a for p in params for a in ("-p", p)), name="sim_bridge"
    )
    probe.wait(
        lambda: all(len(r) >= 3 for r in readings.values()),
        30.0,
        "three readings of every robot's five IR sensors",
    )

    model = IrModel()
    # what the offline kernel reads in the same layout, through the same response curve
    expected = ir_ranges(
        positions, headings, walls=WALLS, circles=[CIRCLE], boxes=[BOX], response=IrResponse()
    )
    assert expected[[0, 1, 2, 3, 4], 0] == pytest.approx([GAP, GAP, 0.06, 0.07, 0.04], abs=5e-4)
    # and the ±37° sensors of robot 2 see the wall, those of robot 4 the box
    assert (expected < model.max_range).sum() == 9
    steps: list[int] = []
    for (i, k), msgs in readings.items():
        msg = msgs[-1]
        assert msg.header.frame_id == f"mona_{i}/ir_{k}"
        assert msg.radiation_type == Range.INFRARED
        assert msg.field_of_view == pytest.approx(IR_FIELD_OF_VIEW)
        assert (msg.min_range, msg.max_range) == pytest.approx((model.min_range, model.max_range))
        # pybullet and the kernel agree within 2 mm, one ADC count is at most 1 mm
        assert msg.range == pytest.approx(expected[i, k], abs=0.003), (i, k)
        steps.extend(np.diff([stamp_to_ns(m.header.stamp) for m in msgs]))

    # the scenario's ir_rate readings per second of sim time (the bridge's ir_rate follows
    # it), stamped with it; the readers are best effort, so a loaded machine may drop one
    # (a step of two periods)
    period = round(1e9 / IR_RATE)
    assert min(steps) == pytest.approx(period, abs=1e3)
    assert np.remainder(np.array(steps) + 1e3, period) == pytest.approx(1e3, abs=1e3)

    # IR model constants that cannot work are refused with the reason; the old ones stay
    (result,) = probe.set_parameters(BRIDGE, [Parameter("ir_max_range", value=0.005)])
    assert not result.successful and "min_range < max_range" in result.reason
    assert probe.get_parameters(BRIDGE, ["ir_max_range"]) == [model.max_range]
    assert "Traceback" not in spawn.logs()
