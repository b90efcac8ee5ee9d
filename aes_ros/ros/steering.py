"""Steer a running swarm: one ``/swarm/cmd``, confirmed by the supervisor (``aes-swarm steer``).

The same public interface any ROS tool uses (``ros2 topic pub /swarm/cmd``): a
``geometry_msgs/Twist`` with linear.{x,y} = v_d and angular.z = ω, then the
supervisor's latched ``/swarm/desired_velocity`` is read until it shows the new
command. :func:`set_enabled` calls ``/swarm/enable`` (std_srvs/SetBool).
"""

from __future__ import annotations

import time

import rclpy
from geometry_msgs.msg import Twist, TwistStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import SetBool

from aes_ros.ros import interface as names
from aes_ros.ros.conversions import drive_to_twist, twist_to_drive
from aes_ros.ros.qos import COMMAND, LATCHED

#: Wall seconds to wait for the supervisor's latched command when keeping a value.
LATCHED_WAIT = 3.0
#: Wall seconds between re-sends of an unconfirmed command.
RESEND_PERIOD = 0.5


def steer(
    direction: tuple[float, float] | list[float] | None,
    omega: float | None,
    timeout: float = 15.0,
) -> tuple[bool, str]:
    """Publish one /swarm/cmd and wait for the supervisor's /swarm/desired_velocity echo.

    A None value keeps the supervisor's current one (read from the latched
    /swarm/desired_velocity). Returns (success, message).
    """
    context = rclpy.Context()
    rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(names.STEER_NODE, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    current: list[TwistStamped] = []
    node.create_subscription(TwistStamped, names.DESIRED_VELOCITY, current.append, LATCHED)
    pub = node.create_publisher(Twist, names.CMD, COMMAND)
    deadline = time.monotonic() + timeout
    try:
        # Wait for the supervisor (its /swarm/cmd subscription and its latched state).
        start = time.monotonic()
        keeps = direction is None or omega is None
        while pub.get_subscription_count() == 0 or (
            not current and (keeps or time.monotonic() < start + LATCHED_WAIT)
        ):
            if time.monotonic() > deadline:
                return False, (
                    "steer: no supervisor found (nobody subscribes /swarm/cmd or publishes "
                    f"/swarm/desired_velocity) within {timeout:g} s; is the swarm running "
                    "in this ROS_DOMAIN_ID?"
                )
            executor.spin_once(timeout_sec=0.05)
        old_direction, old_omega = twist_to_drive(current[-1].twist) if current else (None, None)
        want_direction = tuple(map(float, direction)) if direction is not None else old_direction
        want_omega = float(omega) if omega is not None else old_omega
        cmd = drive_to_twist(want_direction, want_omega)
        want = (*want_direction, want_omega)
        pub.publish(cmd)
        sent = time.monotonic()
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if current:
                got_direction, got_omega = twist_to_drive(current[-1].twist)
                got = (*got_direction, got_omega)
                if all(
                    abs(a - b) <= 1e-9 * max(1.0, abs(b)) for a, b in zip(got, want, strict=True)
                ):
                    return True, (
                        f"steer: supervisor now drives direction ({want[0]:g}, {want[1]:g}), "
                        f"omega {want[2]:g} rad/s"
                    )
            if time.monotonic() - sent > RESEND_PERIOD:  # lost or not yet matched: again
                pub.publish(cmd)
                sent = time.monotonic()
        return False, f"steer: the supervisor did not confirm the command within {timeout:g} s"
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def set_enabled(enabled: bool, timeout: float = 15.0) -> tuple[bool, str]:
    """Call /swarm/enable with ``enabled``; (success, the supervisor's answer or why none)."""
    context = rclpy.Context()
    rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(names.STEER_NODE, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    client = node.create_client(SetBool, names.ENABLE)
    deadline = time.monotonic() + timeout
    asked = f"{names.ENABLE} {str(enabled).lower()}"
    try:
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                return False, (
                    f"steer: no {names.ENABLE} service within {timeout:g} s; is the swarm "
                    "running in this ROS_DOMAIN_ID?"
                )
            executor.spin_once(timeout_sec=0.05)
        future = client.call_async(SetBool.Request(data=enabled))
        executor.spin_until_future_complete(future, max(0.0, deadline - time.monotonic()))
        answer = future.result() if future.done() else None
        if answer is None:
            return False, f"steer: {asked}: no answer within {timeout:g} s"
        verdict = "" if answer.success else "refused: "
        return bool(answer.success), f"steer: {asked}: {verdict}{answer.message}"
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
