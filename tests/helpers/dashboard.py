"""A swarm with its dashboard, and WebSocket viewers of it, for the system tests."""

from __future__ import annotations

import asyncio
import json
import queue
import re
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import aiohttp

from aes_ros.ros import interface as names
from helpers.ros_env import Processes, wait_for

URL = re.compile(rf"{names.DASHBOARD_READY} (http://\S+)")


def printed_url(text: str) -> str | None:
    """The dashboard's URL with its token in ``text`` (a process's output), as printed for
    its owner; None if not there (yet). The node's own log line has no token."""
    return next((m.group(1) for m in URL.finditer(text) if "?token=" in m.group(1)), None)


def dashboard_url(spawn: Processes, proc: subprocess.Popen, timeout: float = 60.0) -> str:
    """The URL with the token that the process ``proc`` (a launch with ``--dashboard``,
    ``aes-swarm dashboard`` or ``aes-dashboard``) printed once its dashboard listens."""
    log = spawn.log(proc)
    found = wait_for(lambda: printed_url(log.read_text()) or proc.poll() is not None, timeout)
    url = printed_url(log.read_text())
    assert found and url, f"no dashboard URL:\n{log.read_text()[-3000:]}"
    return url


def launch_with_dashboard(
    spawn: Processes, out: Path, robots: int = 9, *extra: str, setup: str = "linear"
) -> tuple:
    """``aes-swarm launch --dashboard 0`` of ``robots`` robots (``setup``, until
    stopped); returns the launcher's process and the dashboard's URL."""
    launcher = spawn.start(
        "aes-swarm", "launch", "--setup", setup, "--robots", str(robots), "--duration", "0",
        "--dashboard", "0", "--out", str(out), *extra, name="launch",
    )  # fmt: skip
    return launcher, dashboard_url(spawn, launcher)


def local(url: str) -> str:
    """``url`` with its host made 127.0.0.1 (a server bound to 0.0.0.0 listens there too)."""
    return re.sub(r"^http://[^/:]+", "http://127.0.0.1", url)


def socket_url(url: str) -> str:
    """The WebSocket of the dashboard at ``url`` (its token, if any, kept)."""
    base, _, query = local(url).partition("?")
    return "ws" + base.removeprefix("http").rstrip("/") + "/ws" + (f"?{query}" if query else "")


def origin_of(url: str) -> str:
    """The ``Origin`` the dashboard's own page at ``url`` sends (127.0.0.1, as :func:`local`)."""
    return re.match(r"^http://[^/?]+", local(url)).group(0)


class Viewers:
    """``count`` WebSocket viewers of one dashboard, each in its own connection, read
    in a background event loop. ``frames[v]`` holds (wall time, frame) of viewer v
    as they arrive; :meth:`send` sends a control message as viewer 0 and returns the
    server's result. They say they come from the dashboard's own page (``Origin``), as a
    browser's would."""

    def __init__(self, url: str, count: int = 1) -> None:
        self.url = socket_url(url)
        self.origin = origin_of(url)
        self.frames: list[list[tuple[float, dict[str, Any]]]] = [[] for _ in range(count)]
        self.sheets: list[dict[str, Any]] = []
        self.results: queue.Queue[dict[str, Any]] = queue.Queue()
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        self.sockets: list[aiohttp.ClientWebSocketResponse] = []
        try:
            self._run(self._open(count))
        except BaseException:
            self.close()
            raise

    def _run(self, coro: Any, timeout: float = 30.0) -> Any:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    async def _open(self, count: int) -> None:
        self.session = aiohttp.ClientSession()
        for _ in range(count):
            self.sockets.append(await self.session.ws_connect(self.url, origin=self.origin))
        self.readers = [self.loop.create_task(self._read(v)) for v in range(count)]

    async def _read(self, v: int) -> None:
        async for message in self.sockets[v]:
            data = json.loads(message.data)
            if data["type"] == "frame":
                self.frames[v].append((time.monotonic(), data))
            elif data["type"] == "sheet" and v == 0:
                self.sheets.append(data)
            elif data["type"] == "result" and v == 0:
                self.results.put(data)

    def latest(self, v: int = 0) -> dict[str, Any]:
        return self.frames[v][-1][1]

    def send(self, message: dict[str, Any] | str, timeout: float = 10.0) -> dict[str, Any]:
        text = message if isinstance(message, str) else json.dumps(message)
        self._run(self.sockets[0].send_str(text))
        return self.results.get(timeout=timeout)

    def send_all(self, messages: list[dict[str, Any]], timeout: float = 10.0) -> list[dict]:
        """Send ``messages`` as viewer 0 back to back, then return the server's results."""

        async def send() -> None:
            for message in messages:
                await self.sockets[0].send_str(json.dumps(message))

        self._run(send())
        return [self.results.get(timeout=timeout) for _ in messages]

    def rate(self, v: int, since: float) -> float:
        """Frames per wall second viewer ``v`` received since monotonic time ``since``."""
        times = [t for t, _ in self.frames[v] if t >= since]
        return (len(times) - 1) / (times[-1] - times[0]) if len(times) > 1 else 0.0

    def close(self) -> None:
        async def close() -> None:
            for ws in self.sockets:
                await ws.close()
            await self.session.close()

        self._run(close())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
