"""What the browser dashboard costs, and how fast its page draws.

1. **100 robots, a real swarm**: ``aes-swarm launch --setup linear --robots 100
   --dashboard 0`` in a ROS domain of its own, one viewer in headless Chromium and
   one WebSocket reader in this process (both as the page: the sheet once, then
   frames at the default ``frame_rate``). Over ``--duration`` wall seconds: the
   dashboard process's CPU [% of one core] (target ≤ 10 %), next to the bridge's in
   the same run (its ratio holds across machines), the WebSocket bytes per second
   of one viewer, and the page's pictures per second.
2. **The page alone at 100 and 1000 robots**: ``aes-dashboard`` fed by a pose
   publisher in this process (the sheet of N robots turning slowly, 20 Hz, as the
   bridge publishes it; a real 1000-robot swarm takes minutes to start, and only
   the frames matter to the page), frames sent at 30 Hz so that the page's own
   speed shows: pictures per second drawn by headless Chromium (target ≥ 20 at
   1000 robots) and the milliseconds each takes (1000 / that = what the page could
   draw).

Usage::

    python bench/bench_dashboard.py               # ~1.5 min
    python bench/bench_dashboard.py --duration 20 --screenshot docs/dashboard.png

Prints a table and, as its last line, ``RESULT cpu_pct_100=… bridge_cpu_pct_100=…
ws_kbytes_s_100=… page_fps_100=… page_fps_1000=… draw_ms_1000=… targets_met=yes|no``.
``--screenshot`` saves the page of the 100-robot swarm (the README's picture).
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import aiohttp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from bench_faults import pid_of
from helpers.browser import headless_chromium, page_state, unavailable
from helpers.dashboard import origin_of, printed_url, socket_url
from process_stats import cpu_seconds

from aes_ros import scenario
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.ros import interface as names
from aes_ros.ros.launch.param_files import ros_args, write_scenario

BIN = Path(sys.executable).parent
TARGET_CPU_PCT, TARGET_FPS_1000 = 10.0, 20.0


def wait_url(log: Path, proc: subprocess.Popen, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = printed_url(log.read_text())
        if found:
            return found
        if proc.poll() is not None:
            break
        time.sleep(0.2)
    raise RuntimeError(f"no dashboard URL:\n{log.read_text()[-2000:]}")


class ByteCounter:
    """A WebSocket viewer in a background thread that counts what it receives."""

    def __init__(self, url: str) -> None:
        self.url, self.origin = socket_url(url), origin_of(url)
        self.bytes = 0
        self.frames = 0
        self.ws: aiohttp.ClientWebSocketResponse | None = None
        self.loop = asyncio.new_event_loop()
        threading.Thread(target=self.loop.run_forever, daemon=True).start()
        self.task = asyncio.run_coroutine_threadsafe(self._read(), self.loop)

    async def _read(self) -> None:
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(self.url, origin=self.origin) as ws,
        ):
            self.ws = ws
            async for message in ws:
                self.bytes += len(message.data)
                self.frames += message.data.startswith('{"type": "frame"')

    def close(self) -> None:
        if self.ws is not None:
            asyncio.run_coroutine_threadsafe(self.ws.close(), self.loop).result(10)
            self.task.result(10)  # the reader ends with its socket
        self.loop.call_soon_threadsafe(self.loop.stop)


def page_rate(driver, seconds: float) -> tuple[float, float]:
    """Pictures per second the page drew over ``seconds``, and ms per picture."""
    a = page_state(driver)
    time.sleep(seconds)
    b = page_state(driver)
    draws = b["draws"] - a["draws"]
    return draws / seconds, (b["drawMs"] - a["drawMs"]) / max(draws, 1)


def real_swarm(args, domain: str, work: Path) -> dict[str, float]:
    """Part 1: 100 robots launched with the dashboard, one page and one counter."""
    log = work / "launch.log"
    launcher = subprocess.Popen(
        [str(BIN / "aes-swarm"), "launch", "--setup", "linear", "--robots", "100",
         "--duration", "0", "--dashboard", "0", "--out", str(work / "out")],
        stdout=open(log, "w"), stderr=subprocess.STDOUT, start_new_session=True,
    )  # fmt: skip
    driver = None
    try:
        url = wait_url(log, launcher, 300.0)
        print(f"100 robots: dashboard at {url}", flush=True)
        dashboard, bridge = pid_of(domain, "aes-dashboard"), pid_of(domain, "aes-sim-bridge")
        driver = headless_chromium()
        driver.get(url)
        counter = ByteCounter(url)
        time.sleep(5.0)  # the page and the counter settle
        cpu0 = {p: cpu_seconds(p) for p in (dashboard, bridge)}
        bytes0, t0 = counter.bytes, time.monotonic()
        fps, draw_ms = page_rate(driver, args.duration)
        wall = time.monotonic() - t0
        cpu = {p: 100 * (cpu_seconds(p) - cpu0[p]) / wall for p in (dashboard, bridge)}
        kbytes = (counter.bytes - bytes0) / wall / 1e3
        if args.screenshot is not None:
            args.screenshot.parent.mkdir(parents=True, exist_ok=True)
            driver.save_screenshot(str(args.screenshot))
            print(f"screenshot: {args.screenshot}")
        counter.close()
        return {"cpu_pct": cpu[dashboard], "bridge_cpu_pct": cpu[bridge],
                "ws_kbytes_s": kbytes, "page_fps": fps, "draw_ms": draw_ms}  # fmt: skip
    finally:
        if driver is not None:
            driver.quit()
        launcher.send_signal(signal.SIGINT)
        try:
            launcher.wait(60)
        except subprocess.TimeoutExpired:
            os.killpg(launcher.pid, signal.SIGKILL)


def fed_page(n: int, seconds: float, work: Path) -> tuple[float, float]:
    """Part 2: the page of ``n`` robots from poses published here; (fps, ms per picture)."""
    import rclpy
    from geometry_msgs.msg import PoseArray

    from aes_ros.ros.conversions import arrays_to_poses
    from aes_ros.ros.qos import STREAM_WRITER

    print(f"the page alone, {n} robots …", flush=True)
    sc = scenario.load("linear").with_robots(n)
    scenario_file = write_scenario(sc, work / f"sheet_{n}.yaml")
    log = work / f"dashboard_{n}.log"
    params = {"scenario": str(scenario_file), "port": 0, "frame_rate": 30.0}
    dashboard = subprocess.Popen(
        [str(BIN / "aes-dashboard"), *ros_args(params)],
        stdout=open(log, "w"), stderr=subprocess.STDOUT, start_new_session=True,
    )  # fmt: skip
    rclpy.init()
    node = rclpy.create_node("bench_poses")
    pub = node.create_publisher(PoseArray, names.POSES, STREAM_WRITER)
    home = sc.nominal_positions()
    home = home - home.mean(axis=0)
    start = time.monotonic()

    def publish() -> None:
        t = time.monotonic() - start
        turn = 0.05 * t
        c, s = math.cos(turn), math.sin(turn)
        msg = PoseArray()
        msg.header.frame_id = names.WORLD_FRAME
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int((t % 1) * 1e9)
        positions = home @ np.array([[c, s], [-s, c]]) + [0.02 * t, 0.0]
        msg.poses = arrays_to_poses(positions, np.full(n, turn + math.pi / 2))
        pub.publish(msg)

    node.create_timer(0.05, publish)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            rclpy.spin_once(node, timeout_sec=0.1)

    spinner = threading.Thread(target=spin)
    spinner.start()
    driver = None
    try:
        url = wait_url(log, dashboard, 60.0)
        driver = headless_chromium()
        driver.get(url)
        deadline = time.monotonic() + 30.0
        while ((page_state(driver) or {}).get("drawn") or {}).get("robots") != n:
            if time.monotonic() > deadline:
                raise RuntimeError(f"the page did not draw {n} robots")
            time.sleep(0.2)
        time.sleep(2.0)
        return page_rate(driver, seconds)
    finally:
        if driver is not None:
            driver.quit()
        stop.set()
        spinner.join(5)
        node.destroy_node()
        rclpy.try_shutdown()
        dashboard.send_signal(signal.SIGINT)
        dashboard.wait(30)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=10.0, help="each measurement [s]")
    add_deprecated(parser, "--seconds", "--duration")
    parser.add_argument("--domain", default="96", help="the ROS_DOMAIN_ID of the runs")
    parser.add_argument("--screenshot", type=Path, default=None, help="save the 100-robot page")
    args = parser.parse_args(argv)
    if (why := unavailable()) is not None:
        print(f"bench_dashboard: {why}", file=sys.stderr)
        return 2
    os.environ["ROS_DOMAIN_ID"] = args.domain
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    with tempfile.TemporaryDirectory(prefix="aes-bench-dashboard-") as tmp:
        work = Path(tmp)
        real = real_swarm(args, args.domain, work)
        fed = {n: fed_page(n, args.duration, work) for n in (100, 1000)}
    print(f"\n{'':<44}{'value':>10}{'target':>9}")
    rows = [
        ("dashboard CPU, 100 robots [% core]", real["cpu_pct"], f"<= {TARGET_CPU_PCT:g}"),
        ("bridge CPU, same run [% core]", real["bridge_cpu_pct"], "-"),
        ("dashboard / bridge CPU", real["cpu_pct"] / real["bridge_cpu_pct"], "-"),
        ("WebSocket, one viewer [kB/s]", real["ws_kbytes_s"], "-"),
        ("page, 100 robots, 15 Hz frames [pictures/s]", real["page_fps"], ">= 10"),
        ("page, 100 robots, 30 Hz frames [pictures/s]", fed[100][0], "-"),
        ("page, 1000 robots, 30 Hz frames [pictures/s]", fed[1000][0], f">= {TARGET_FPS_1000:g}"),
        ("drawing one picture, 100 robots [ms]", fed[100][1], "-"),
        ("drawing one picture, 1000 robots [ms]", fed[1000][1], "-"),
    ]
    for label, value, target in rows:
        print(f"{label:<44}{value:>10.2f}{target:>9}")
    met = (
        real["cpu_pct"] <= TARGET_CPU_PCT
        and fed[1000][0] >= TARGET_FPS_1000
        and real["page_fps"] >= 10
    )
    print(
        f"RESULT cpu_pct_100={real['cpu_pct']:.1f} bridge_cpu_pct_100={real['bridge_cpu_pct']:.1f} "
        f"ws_kbytes_s_100={real['ws_kbytes_s']:.1f} page_fps_100={fed[100][0]:.1f} "
        f"page_fps_1000={fed[1000][0]:.1f} draw_ms_1000={fed[1000][1]:.2f} "
        f"targets_met={'yes' if met else 'no'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
