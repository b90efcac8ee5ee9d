"""A running dashboard given what a careless or hostile participant sends, and a robot
that stops answering: it logs a throttled warning and keeps serving every viewer.

One started system (``aes-swarm dashboard``, robot node 1, the probe publishing the
poses of three robots) for every check: ``/swarm/poses`` with no poses, 10⁵ poses
(5.6 MB), another frame and NaN are dropped and the page keeps the last good swarm;
the robot's parameter service hung (SIGSTOP) past the dashboard's 5 s while a gain
change waits: the viewer is told, the late answer is logged, and the dashboard still
serves and steers. The pure parts: tests/unit/test_dashboard_bad_input.py.
"""

from __future__ import annotations

import math
import os
import signal
import time
import urllib.request

import numpy as np
from geometry_msgs.msg import PoseArray
from helpers.dashboard import Viewers, dashboard_url, local
from helpers.messages import poses_msg
from helpers.robot import NODE_1, NOISE_OFF, robot_1
from helpers.ros_env import TIMEOUT, wait_for

from aes_ros.ros import interface as names
from aes_ros.ros.cdr import PoseArrayEncoder
from aes_ros.ros.qos import SENSOR
from dashboard_node.requests import CALL_TIMEOUT

N = 3
XY = np.array([[-0.2, 0.0], [0.0, 0.0], [0.25, 0.0]])
YAW = np.zeros(N)


def test_bad_poses_and_a_hung_robot_leave_the_dashboard_serving(spawn, probe):
    dashboard = spawn.start(
        "aes-swarm", "dashboard", "--setup", "linear", "--robots", str(N), "--port", "0",
        name="dashboard",
    )  # fmt: skip
    robot = spawn.start(*robot_1("-p", "neighbor_timeout:=1000.0", *NOISE_OFF), name="robot")
    url = dashboard_url(spawn, dashboard)
    log = spawn.log(dashboard)
    poses = probe.publisher(PoseArray, names.POSES, SENSOR, subscribers=2)
    clock = [1.0]

    def good() -> None:
        clock[0] += 0.1
        poses.publish(poses_msg(XY, YAW, clock[0]))

    probe.every(0.1, good)
    viewer = Viewers(url)
    try:
        probe.wait(lambda: viewer.frames[0] and "x" in viewer.latest(), TIMEOUT, "a frame")

        # bad poses: each dropped with its own warning, the page keeps the good swarm
        many = 10**5
        huge = PoseArrayEncoder(many).encode(2, 0, np.zeros((many, 2)), np.zeros(many))
        map_frame = poses_msg(XY + 5.0, YAW, 2.0)
        map_frame.header.frame_id = "map"
        for bad, warning in [
            (PoseArray(header=poses_msg(XY, YAW, 2.0).header), "dropped /swarm/poses, no poses"),
            (huge, f"too many poses: {many}"),
            (map_frame, "PoseArray in frame 'map'"),
        ]:
            probe.until(lambda bad=bad: poses.publish(bad), lambda w=warning: w in log.read_text())
        time.sleep(0.5)
        frame = viewer.latest()
        assert frame["n"] == N and frame["x"] == XY[:, 0].tolist(), frame

        # a gain change the robot takes: the dashboard has found it
        alpha = {"type": "gain", "name": "alpha", "value": 0.05}
        probe.until(lambda: None, lambda: "accepted by 1 of 1" in viewer.send(alpha)["message"])

        # the robot hangs with a gain change waiting: told after 5 s, logged when it answers
        os.kill(robot.pid, signal.SIGSTOP)
        try:
            frames = len(viewer.frames[0])
            result = viewer.send({**alpha, "value": 0.07}, timeout=CALL_TIMEOUT + 10.0)
            assert not result["ok"] and "no answer" in result["message"], result
            assert len(viewer.frames[0]) > frames + 10  # frames went on meanwhile
            time.sleep(1.0)  # hung past the viewer's timeout
        finally:
            os.kill(robot.pid, signal.SIGCONT)
        assert wait_for(lambda: "late answer" in log.read_text(), 10.0), log.read_text()[-2000:]
        assert probe.get_parameters(NODE_1, ["alpha"]) == [0.07]  # it did take it, late

        # still serving: the page, a new viewer's frames, and a control carried out
        with urllib.request.urlopen(local(url), timeout=10) as response:
            assert response.status == 200
        second = Viewers(url)
        try:
            probe.wait(lambda: second.frames[0], 10.0, "a frame for a new viewer")
            assert second.latest()["n"] == N
        finally:
            second.close()
        assert viewer.send(alpha)["ok"]

        # NaN: the last kind, more than the 5 s throttle after the frame's warning
        nan = poses_msg(XY, YAW, 3.0)
        nan.poses[1].position.x = math.nan
        probe.until(lambda: poses.publish(nan), lambda: "non-finite" in log.read_text())
        assert viewer.latest()["n"] == N
    finally:
        viewer.close()
    assert dashboard.poll() is None and robot.poll() is None
    dashboard.send_signal(signal.SIGINT)
    assert dashboard.wait(30) == 0
    text = log.read_text()
    assert "Traceback" not in text and "failed" not in text, text[-3000:]
    assert "Traceback" not in spawn.log(robot).read_text()  # it had every bad message too
