"""Mona driver: K real Monas on ROS 2 over the Mona link v1 (docs/mona_protocol.md).

Robot 0 on a USB serial adapter, robot 1 on Wi-Fi::

    aes-mona-driver --link 0=serial:/dev/ttyUSB0@115200 --link 1=udp:192.168.1.41:4210 \\
        --ros-args -p timeout_ms:=500

``--links FILE`` reads the same strings from a YAML list. A link that cannot be parsed
or opened at start ends the driver with exit code 2 and the reason.
"""

from __future__ import annotations

import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState, Range
from std_msgs.msg import Bool

from aes_ros.mona.geometry import MonaGeometry, twist_from_wheels, wheels_from_twist
from aes_ros.mona.messages import BATTERY_LOW, Hello, Ping, Pong, Stop, Telemetry, Wheels
from aes_ros.mona.sensors import IR_FIELD_OF_VIEW, IrModel, battery_volts, integrate_pose
from aes_ros.params import ParameterError
from aes_ros.ros import interface as names
from aes_ros.ros import parameters as rp
from aes_ros.ros.node_tools import ThrottledWarnings
from aes_ros.ros.qos import LATCHED, LATEST_COMMAND, SENSOR
from mona_driver.diagnostics import link_status, udp_status
from mona_driver.robot import RobotLink
from mona_driver.transport import SerialPort, UdpHub, UdpPort

#: The longest odometry step between two TELEMETRY frames [s]: a longer gap (a link
#: that was down) is not integrated as if the wheels had kept their speed.
MAX_ODOM_STEP = 0.2


class MonaDriverNode(Node):
    """Drives the robots of ``links`` (node ``mona_driver``).

    One node for all robots: they share every parameter, and K nodes would add K sets
    of parameter services and DDS endpoints for nothing. Parameters:

    - ``timeout_ms`` (int, ms, default 500): the WHEELS timeout; the last ``cmd_vel``
      is resent every third of it while it is younger than the timeout.
    - ``poll_rate_hz`` (double, Hz, default 100.0, read-only): how often links are read.
    - ``ping_period`` (double, s, default 1.0, read-only): PING for the round-trip time.
    - ``silent_after`` (double, s, default 1.0): a link without a valid frame for this
      long is reported silent.
    - ``hello_timeout`` (double, s, default 3.0): how long a serial link that opened
      waits for the robot's HELLO before WHEELS and PING go out; a robot without one
      by then is reported (and driven).
    - ``check_robot_id`` (bool, default true): a robot whose HELLO names another robot
      id gets nothing (no WHEELS, PING or STOP) until it names the link's; false drives
      it anyway (robots whose EEPROM id was never set all say the build's id).
    - ``odom_frame``, ``base_frame``, ``ir_frame`` (string, ``{id}`` and ``{k}`` are
      replaced): frames of wheel odometry and IR ranges.
    - ``ir_gain`` (m·counts, 10.0), ``ir_offset`` (counts, 50.0), ``ir_min_range`` (m,
      0.01), ``ir_max_range`` (m, 0.10), ``ir_falling`` (bool, true): the IR model
      (:class:`aes_ros.mona.sensors.IrModel`).
    """

    def __init__(self, links: list[RobotLink], hub: UdpHub | None = None, **kwargs) -> None:
        super().__init__(names.MONA_DRIVER_NODE, **kwargs)
        self.links = links
        self.hub = hub
        self.geometry = MonaGeometry()
        self.warn = ThrottledWarnings(self.get_logger())
        self.enabled = True
        self._strangers_warned = 0
        self._declare_parameters()
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self._odom: dict[int, tuple[float, float, float, float | None]] = {}
        self._by_address = {
            link.transport.address: link for link in links if isinstance(link.transport, UdpPort)
        }
        self._pubs: dict[int, tuple] = {}
        for link in links:
            i = link.robot_id
            topic = lambda name, i=i: names.robot_topic(i, name)  # noqa: E731
            self._pubs[i] = (
                self.create_publisher(Odometry, topic(names.WHEEL_ODOM), SENSOR),
                [self.create_publisher(Range, topic(f"{names.IR}_{k}"), SENSOR) for k in range(5)],
                self.create_publisher(BatteryState, topic(names.BATTERY), SENSOR),
            )
            self.create_subscription(
                Twist, topic(names.CMD_VEL), lambda m, link=link: self.on_cmd_vel(link, m),
                LATEST_COMMAND,
            )  # fmt: skip
            self._odom[i] = (0.0, 0.0, 0.0, None)
        self.create_subscription(Bool, names.ENABLED, self.on_enabled, LATCHED)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, names.DIAGNOSTICS, LATCHED)
        now = time.monotonic()
        for link in links:
            link.opened_at = now
        self._next_ping = now
        self.create_timer(1.0 / self.get_parameter("poll_rate_hz").value, self.on_poll)
        self.create_timer(1.0, self.on_diagnostics)
        self.create_timer(1.0, self.on_device_check)
        udp = f", UDP port {hub.port}" if hub is not None else ""
        self.get_logger().info(
            f"{names.MONA_DRIVER_READY} {len(links)} robots "
            f"({', '.join(str(link.spec) for link in links)}){udp}"
        )

    def _declare_parameters(self) -> None:
        fd, text = rp.float_descriptor, rp.text_descriptor
        params = [
            ("timeout_ms", 500, rp.int_descriptor("WHEELS timeout [ms]", 20, 10000)),
            ("poll_rate_hz", 100.0, fd("link reads a second", "Hz", 5.0, 1000.0, read_only=True)),
            ("ping_period", 1.0, fd("time between PINGs", "s", 0.1, 60.0, read_only=True)),
            ("silent_after", 1.0, fd("no valid frame this long: silent", "s", 0.1, 60.0)),
            ("hello_timeout", 3.0, fd("no HELLO this long: reported", "s", 0.1, 600.0)),
            (
                "check_robot_id",
                True,
                rp.bool_descriptor("send nothing to a robot whose HELLO names another id"),
            ),
            ("odom_frame", "mona_{id}/odom", text("frame of wheel_odom ({id}: robot id)")),
            ("base_frame", "mona_{id}/base_link", text("the robot's body frame")),
            ("ir_frame", "mona_{id}/ir_{k}", text("frame of IR sensor k")),
            ("ir_gain", IrModel.gain, fd("IR: range = gain / (raw - offset)", "m", 1e-6, 1e6)),
            ("ir_offset", IrModel.offset, fd("IR: ambient reading", "ADC counts", -1e5, 1e5)),
            ("ir_min_range", IrModel.min_range, fd("IR: nearest range", "m", 0.0, 10.0)),
            ("ir_max_range", IrModel.max_range, fd("IR: farthest range", "m", 1e-3, 10.0)),
            (
                "ir_falling",
                IrModel.falling,
                rp.bool_descriptor("IR: the reading falls as an obstacle comes closer"),
            ),
        ]
        for name, default, descriptor in params:
            self.declare_parameter(name, default, descriptor)
        self.ping_period = float(self.get_parameter("ping_period").value)
        self.ir_model = self._ir_model({})
        reason = self.ir_model.check()
        if reason is not None:
            raise ParameterError(reason)

    def _ir_model(self, changed: dict) -> IrModel:
        def value(name: str) -> float:
            return float(changed.get(name, self.get_parameter(name).value))

        return IrModel(
            value("ir_gain"),
            value("ir_offset"),
            value("ir_min_range"),
            value("ir_max_range"),
            bool(changed.get("ir_falling", self.get_parameter("ir_falling").value)),
        )

    def on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        changed = {p.name: p.value for p in params}
        model = self._ir_model(changed)
        reason = model.check()
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        self.ir_model = model
        return SetParametersResult(successful=True)

    @property
    def timeout(self) -> float:
        """The WHEELS timeout [s]."""
        return 1e-3 * self.get_parameter("timeout_ms").value

    # ----------------------------------------------------------------- commands

    def on_cmd_vel(self, link: RobotLink, msg: Twist) -> None:
        v, omega = msg.linear.x, msg.angular.z
        if not (math.isfinite(v) and math.isfinite(omega)):
            link.stats.bad_commands += 1
            self.warn(f"dropped mona_{link.robot_id} cmd_vel: a non-finite value ({v}, {omega})")
            return
        if not self.enabled:
            return
        left, right = wheels_from_twist(v, omega, self.geometry)
        now = time.monotonic()
        link.command = Wheels(left, right, int(self.get_parameter("timeout_ms").value))
        link.command_at = now
        self._send(link, link.command, now)

    def on_enabled(self, msg: Bool) -> None:
        enabled = bool(msg.data)
        if enabled == self.enabled:
            return
        self.enabled = enabled
        now = time.monotonic()
        if not enabled:
            for link in self.links:
                link.command = None
                self._stop(link, now)
        self.get_logger().info(
            f"swarm {'enabled' if enabled else 'disabled: STOP sent to every robot'}"
        )

    def _stop(self, link: RobotLink, now: float) -> None:
        # a datagram can be lost: a second STOP costs nothing
        for _ in range(2 if isinstance(link.transport, UdpPort) else 1):
            self._send(link, Stop(), now)

    def _send(self, link: RobotLink, msg: Wheels | Stop | Ping, now: float) -> None:
        hello_after = float(self.get_parameter("hello_timeout").value)
        if not isinstance(msg, Stop) and link.awaits_hello(now, hello_after):
            # a robot stops saying HELLO at its first valid frame: let it say it first
            # (a WHEELS held back here goes out from on_poll if still fresh)
            return
        if link.other_robot() is not None and self.get_parameter("check_robot_id").value:
            return  # another robot's: not ours to drive, nor to stop
        if link.transport.is_open:
            reason = link.send(msg, now)
            if reason is not None:
                self.warn(f"link of mona_{link.robot_id} down: {reason}")

    # ----------------------------------------------------------------- the links

    def on_poll(self) -> None:
        now = time.monotonic()
        if self.hub is not None:
            for address, data in self.hub.receive(set(self._by_address)):
                link = self._by_address[address]
                # one frame per datagram: a missing delimiter must not join it to the next
                self._handle(link, data if data.endswith(b"\x00") else data + b"\x00", now)
            # warned at most every 5 s, and only while new ones come
            if self.hub.strangers > self._strangers_warned and self.warn(
                f"dropped UDP datagrams from addresses not in the links: {self.hub.strangers} "
                f"so far, the last from {self.hub.last_stranger}"
            ):
                self._strangers_warned = self.hub.strangers
        for link in self.links:
            if isinstance(link.transport, SerialPort):
                self._poll_serial(link, now)
            fresh = link.fresh_command(now, self.timeout) if self.enabled else None
            if fresh is not None and now - link.wheels_sent_at >= self.timeout / 3.0:
                self._send(link, fresh, now)
        if now >= self._next_ping:
            self._next_ping = now + self.ping_period
            for link in self.links:
                self._send(link, Ping(), now)

    def on_device_check(self) -> None:
        """Reopen a serial link whose device path now leads to another device (once a
        second: resolving a path costs system calls)."""
        now = time.monotonic()
        for link in self.links:
            port = link.transport
            moved_to = port.moved_to() if isinstance(port, SerialPort) else None
            if moved_to is not None:
                link.drop(f"{link.spec.device} now leads to {moved_to}", now)
                self.warn(f"link of mona_{link.robot_id} moved: {link.stats.last_error}; reopening")

    def _poll_serial(self, link: RobotLink, now: float) -> None:
        port = link.transport
        if not port.is_open:
            if now < link.retry_at:
                return
            reason = link.open(now)
            if reason is not None:
                self.warn(f"link of mona_{link.robot_id} down: {reason}; retrying")
                return
            link.stats.reconnects += 1
            self.get_logger().info(f"link of mona_{link.robot_id} reopened ({link.spec})")
            return
        try:
            data = port.read()
        except OSError as exc:
            link.drop(f"{exc.strerror or exc}", now)
            self.warn(f"link of mona_{link.robot_id} down: {link.stats.last_error}; reopening")
            return
        if data:
            self._handle(link, data, now)

    def _handle(self, link: RobotLink, data: bytes, now: float) -> None:
        got, errors = link.receive(data, now)
        for exc in errors:
            self.warn(f"mona_{link.robot_id} bad frame ({exc.kind}): {exc}; dropped")
        for msg in got:
            if isinstance(msg, Telemetry):
                self._publish_telemetry(link, msg)
            elif isinstance(msg, Hello):
                self._on_hello(link, msg)
            elif isinstance(msg, Pong):
                pass  # its round-trip time is in the link's stats

    def _on_hello(self, link: RobotLink, hello: Hello) -> None:
        self.get_logger().info(
            f"mona_{link.robot_id}: HELLO from {hello.hw!r} firmware "
            f"{hello.fw_major}.{hello.fw_minor}, robot id {hello.robot_id}"
        )
        if hello.robot_id != link.robot_id:
            refused = self.get_parameter("check_robot_id").value
            self.warn(
                f"mona_{link.robot_id} id mismatch: the robot on {link.spec} says it is "
                f"{hello.robot_id}; "
                + ("nothing is sent to it (check_robot_id:=false drives it anyway)" if refused
                   else f"driven as mona_{link.robot_id} (check_robot_id is false)")
            )  # fmt: skip

    # ----------------------------------------------------------------- telemetry

    def _publish_telemetry(self, link: RobotLink, t: Telemetry) -> None:
        i = link.robot_id
        odom_pub, ir_pubs, battery_pub = self._pubs[i]
        now = time.monotonic()
        stamp = self.get_clock().now().to_msg()
        v, omega = twist_from_wheels(t.left, t.right, self.geometry)
        x, y, theta, last = self._odom[i]
        if last is not None:
            x, y, theta = integrate_pose(x, y, theta, v, omega, min(now - last, MAX_ODOM_STEP))
        self._odom[i] = (x, y, theta, now)
        odom = Odometry()
        odom.header.stamp = stamp
        odom.header.frame_id = self._frame("odom_frame", i)
        odom.child_frame_id = self._frame("base_frame", i)
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation.z = math.sin(0.5 * theta)
        odom.pose.pose.orientation.w = math.cos(0.5 * theta)
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = v, omega
        odom_pub.publish(odom)
        ranges = self.ir_model.range(t.ir)
        for k, (pub, r) in enumerate(zip(ir_pubs, ranges, strict=True)):
            msg = Range(radiation_type=Range.INFRARED, field_of_view=IR_FIELD_OF_VIEW)
            msg.header.stamp = stamp
            msg.header.frame_id = self._frame("ir_frame", i, k)
            msg.min_range, msg.max_range = self.ir_model.min_range, self.ir_model.max_range
            msg.range = float(r)
            pub.publish(msg)
        battery = BatteryState(voltage=battery_volts(t.battery_mv), present=True)
        battery.header.stamp = stamp
        battery.header.frame_id = self._frame("base_frame", i)
        # not measured by a Mona: NaN, as sensor_msgs/BatteryState asks
        battery.current = battery.charge = battery.capacity = math.nan
        battery.design_capacity = battery.percentage = battery.temperature = math.nan
        battery.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LION
        if t.flags & BATTERY_LOW:
            battery.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_DEAD
        battery_pub.publish(battery)

    def _frame(self, parameter: str, robot_id: int, k: int = 0) -> str:
        return str(self.get_parameter(parameter).value).replace("{id}", str(robot_id)).replace(
            "{k}", str(k))  # fmt: skip

    # ----------------------------------------------------------------- diagnostics

    def on_diagnostics(self) -> None:
        now = time.monotonic()
        silent = float(self.get_parameter("silent_after").value)
        hello_after = float(self.get_parameter("hello_timeout").value)
        statuses = [
            link_status(
                link,
                now,
                silent_after=silent,
                hello_after=hello_after,
                refuse_other=self.get_parameter("check_robot_id").value,
            )
            for link in self.links
        ]
        for link, status in zip(self.links, statuses, strict=True):
            if link.hello is None and "no HELLO" in status.message:
                self.warn(f"mona_{link.robot_id} no HELLO: {status.message} ({link.spec})")
        if self.hub is not None:
            statuses.append(udp_status(self.hub))
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_pub.publish(msg)

    def destroy_node(self) -> None:
        """STOP to every robot, then close the links."""
        now = time.monotonic()
        for link in self.links:
            link.command = None
            self._stop(link, now)
        self.get_logger().info(f"STOP sent to {len(self.links)} robots")
        for link in self.links:
            link.transport.close()
        if self.hub is not None:
            self.hub.close()
        super().destroy_node()
