"""The dashboard's web server: the page, its assets and one WebSocket per viewer (aiohttp).

Why aiohttp: one well-kept package gives the HTTP server, WebSockets and the
asyncio loop (Starlette would need uvicorn and the ``websockets`` package beside
it), and it runs in the dashboard process next to the rclpy node's thread. The
page is plain HTML, CSS and a JavaScript module served from this package
(``dashboard_node/static``): no CDN, nothing to build.

- ``GET /``: the page; ``GET /static/<file>``: its assets;
- ``GET /ws``: a viewer's WebSocket. The server sends the sheet (``type: sheet``)
  once, then a frame (``type: frame``) at ``frame_rate``; the viewer sends control
  messages (:mod:`dashboard_node.controls`) and gets a ``type: result`` for each.

Safety: on a loopback address anyone on this machine may connect. On any other
address every request needs the token (``?token=…`` in the URL, which then sets a
cookie for the page's assets and WebSocket): without it HTTP gets 401 and the
WebSocket is refused before it opens, and each refusal is logged. Every control
message is checked before anything is published, and a viewer may send at most
10 a second (bursts of 20).
"""

from __future__ import annotations

import asyncio
import hmac
import json
import secrets
import time
from importlib import resources
from typing import Any

from aiohttp import WSMsgType, web

from aes_ros.ros import interface as names
from dashboard_node.controls import ControlError, RateLimit, SetGain, parse_control
from dashboard_node.node import CALL_TIMEOUT, DashboardNode

#: Files the page may load (nothing else under static/ is served).
ASSETS = {"index.html": "text/html", "app.js": "text/javascript", "style.css": "text/css"}
COOKIE = "aes_dashboard_token"
LOOPBACK = ("127.0.0.1", "localhost", "::1")


def needs_token(host: str) -> bool:
    """True unless the server only listens on this machine."""
    return host not in LOOPBACK


class Dashboard:
    """The web side of one dashboard node."""

    def __init__(self, node: DashboardNode, host: str, port: int, token: str) -> None:
        self.node, self.host, self.port = node, host, port
        self.token = token or (secrets.token_urlsafe(16) if needs_token(host) else "")
        self.viewers: set[web.WebSocketResponse] = set()
        self.frames_sent = 0
        self.app = web.Application(middlewares=[self.guard])
        self.app.add_routes(
            [
                web.get("/", self.on_page),
                web.get("/static/{name}", self.on_asset),
                web.get("/ws", self.on_socket),
            ]
        )

    @property
    def url(self) -> str:
        query = f"?token={self.token}" if self.token else ""
        return f"http://{self.host}:{self.port}/{query}"

    # --- access ---------------------------------------------------------------------

    def allowed(self, request: web.Request) -> bool:
        if not self.token:
            return True
        given = request.query.get("token") or request.cookies.get(COOKIE, "")
        return hmac.compare_digest(given.encode(), self.token.encode())

    @web.middleware
    async def guard(self, request: web.Request, handler: Any) -> web.StreamResponse:
        if not self.allowed(request):
            self.node._warn(f"refused {request.path}: no valid token (from {request.remote})")
            return web.Response(status=401, text="401: this dashboard needs its token (?token=…)")
        response = await handler(request)
        if self.token and request.query.get("token"):
            response.set_cookie(COOKIE, self.token, httponly=True, samesite="Strict")
        return response

    # --- HTTP ----------------------------------------------------------------------

    async def on_page(self, request: web.Request) -> web.Response:
        return self._asset("index.html")

    async def on_asset(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        if name not in ASSETS:
            raise web.HTTPNotFound()
        return self._asset(name)

    @staticmethod
    def _asset(name: str) -> web.Response:
        text = resources.files("dashboard_node").joinpath(f"static/{name}").read_text()
        return web.Response(text=text, content_type=ASSETS[name], charset="utf-8")

    # --- viewers --------------------------------------------------------------------

    async def on_socket(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=1 << 16)
        await ws.prepare(request)
        limit = RateLimit()
        with self.node.lock:
            sheet = self.node.view.sheet_message()
        await ws.send_str(json.dumps(sheet))
        self.viewers.add(ws)
        try:
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    await ws.send_str(json.dumps(await self.control(message.data, limit)))
                elif message.type == WSMsgType.BINARY:
                    await ws.send_str(json.dumps(_result(False, "send JSON text, not binary")))
        finally:
            self.viewers.discard(ws)
        return ws

    async def control(self, text: str, limit: RateLimit) -> dict[str, Any]:
        """Check one control message and, if it passes, have the node carry it out."""
        if not limit.allow(time.monotonic()):
            return _result(False, "too many control messages: at most 10 a second")
        try:
            control = parse_control(text)
        except ControlError as exc:
            return _result(False, str(exc))
        try:
            ok, message = await asyncio.wait_for(
                asyncio.wrap_future(self.node.submit(control)), CALL_TIMEOUT
            )
        except TimeoutError:
            return _result(False, "no answer within 5 s")
        if ok and isinstance(control, SetGain):
            self.node.accepted(control)
        return _result(ok, message)

    async def broadcast(self, stop: asyncio.Event) -> None:
        """A frame to every viewer at ``frame_rate``; a viewer too slow to take one
        misses it instead of holding the others up."""
        period = 1.0 / self.node.get_parameter("frame_rate").value
        n = None
        sending: dict[web.WebSocketResponse, asyncio.Task] = {}
        while not stop.is_set():
            await asyncio.sleep(period)
            # one frame for the viewers and /swarm/markers; none when nobody wants one
            frame = self.node.frame_tick(bool(self.viewers), time.monotonic())
            if frame is None or not self.viewers:
                continue
            sheet = None
            if frame["n"] != n:
                with self.node.lock:
                    sheet = self.node.view.sheet_message()
            n = frame["n"]
            text = json.dumps(frame)
            for ws in list(self.viewers):
                if ws in sending and not sending[ws].done():
                    continue
                sending[ws] = asyncio.create_task(self._send(ws, sheet, text))
            self.frames_sent += 1
            for ws in [w for w in sending if w not in self.viewers]:
                del sending[ws]

    @staticmethod
    async def _send(ws: web.WebSocketResponse, sheet: dict | None, text: str) -> None:
        try:
            if sheet is not None:
                await ws.send_str(json.dumps(sheet))
            await ws.send_str(text)
        except (ConnectionError, RuntimeError):
            pass  # it went away; the socket's handler forgets it

    async def serve(self, stop: asyncio.Event) -> None:
        """Listen until ``stop`` is set; say the URL once listening."""
        runner = web.AppRunner(self.app, access_log=None)
        await runner.setup()
        site = web.TCPSite(runner, self.host, self.port)
        await site.start()
        if self.port == 0:
            self.port = runner.addresses[0][1]
        self.node.get_logger().info(f"{names.DASHBOARD_READY} {self.url}")
        try:
            await self.broadcast(stop)
        finally:
            for ws in list(self.viewers):
                await ws.close()
            await runner.cleanup()
            self.node.get_logger().info(
                f"stopped: {self.frames_sent} frames sent, "
                f"{self.node.markers_published} marker arrays published, "
                f"{self.node.frames_made} frames made"
            )


def _result(ok: bool, message: str) -> dict[str, Any]:
    return {"type": "result", "ok": ok, "message": message}
