"""The dashboard's web server: the page, its assets and one WebSocket per viewer (aiohttp).

Why aiohttp: one well-kept package gives the HTTP server, WebSockets and the
asyncio loop (Starlette would need uvicorn and the ``websockets`` package beside
it), and it runs in the dashboard process next to the rclpy node's thread. The
page is plain HTML, CSS and a JavaScript module served from this package
(``dashboard_node/static``): no CDN, nothing to build.

- ``GET /``: the page; ``GET /static/<file>``: its assets;
- ``GET /ws``: a viewer's WebSocket. The server sends the sheet (``type: sheet``)
  and whether this viewer may steer (``type: access``, ``control``: true or false)
  once, then a frame (``type: frame``) at ``frame_rate``; the viewer sends control
  messages (:mod:`dashboard_node.controls`) and gets a ``type: result`` for each.

Access (:mod:`dashboard_node.access`; the table is in docs/dashboard.md): every
request needs a ``Host`` header naming this server, and the WebSocket (and any
request that carries an ``Origin``) this server's own origin, else HTTP 403.
Control messages need the token (``?token=…`` in the URL, which then sets a
cookie for the page's assets and WebSocket); on a loopback address viewing does
not, on any other address every request does (HTTP 401). Wrong tokens lock their
address out for a minute (HTTP 429); refusals are logged, throttled. At most
:data:`~dashboard_node.access.MAX_VIEWERS` viewers (HTTP 503), 10 control messages
a second each (bursts of 20) and 20 a second of all of them together.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import hmac
import json
import threading
import time
from importlib import resources
from typing import Any, Protocol

from aiohttp import WSMsgType, web
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.parameter import Parameter

from aes_ros.ros import interface as names
from aes_ros.ros.dashboard_token import new_token, with_token
from aes_ros.ros.node_tools import ThrottledWarnings
from dashboard_node.access import (
    CONTROL_RATE,
    MAX_VIEWERS,
    Failures,
    Site,
    is_loopback,
)
from dashboard_node.controls import Control, ControlError, RateLimit, SetGain, parse_control
from dashboard_node.requests import CALL_TIMEOUT
from dashboard_node.view import SwarmView

#: Files the page may load (nothing else under static/ is served).
ASSETS = {"index.html": "text/html", "app.js": "text/javascript", "style.css": "text/css"}
#: On every response: no framing, no sniffing, no Referer (the token is in the URL).
HEADERS = {
    "Content-Security-Policy": (
        "default-src 'self'; connect-src 'self'; img-src 'self' data:; object-src 'none'; "
        "base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    ),
    "X-Frame-Options": "DENY",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}
#: Methods that change nothing (every other one needs this server's Origin).
SAFE_METHODS = ("GET", "HEAD", "OPTIONS")
#: Set by the guard: whether the request's token lets it steer.
MAY_CONTROL = web.RequestKey("may_control", bool)
NO_CONTROL = "refused: this viewer has no token; open the URL the dashboard printed to steer"


def needs_token(host: str) -> bool:
    """True if even viewing needs the token: the server listens beyond this machine."""
    return not is_loopback(host)


class DashboardSource(Protocol):
    """What the web server uses of its node (:class:`dashboard_node.node.DashboardNode`)."""

    lock: threading.Lock
    view: SwarmView
    markers_published: int
    frames_made: int
    _warn: ThrottledWarnings

    def submit(self, control: Control) -> concurrent.futures.Future: ...

    def accepted(self, control: SetGain) -> None: ...

    def frame_tick(self, viewers: bool, now: float) -> dict[str, Any] | None: ...

    def get_parameter(self, name: str) -> Parameter: ...

    def get_logger(self) -> RcutilsLogger: ...


class Dashboard:
    """The web side of one dashboard node; ``token`` None: one is made up. With
    ``print_url`` the URL with the token goes to stdout once listening (the node's
    log and /rosout get it without the token)."""

    def __init__(
        self,
        node: DashboardSource,
        host: str,
        port: int,
        token: str | None = None,
        *,
        print_url: bool = False,
    ) -> None:
        self.node, self.host, self.port = node, host, port
        self.token = token or new_token()
        self.print_url = print_url
        self.site = Site(host, port)
        self.failures = Failures()
        self.controls = RateLimit(*CONTROL_RATE)  # of all viewers together
        self.viewers: set[web.WebSocketResponse] = set()
        self.opening = 0  # viewers whose WebSocket is being opened
        self.frames_sent = 0
        self.app = web.Application(middlewares=[self.guard])
        self.app.on_response_prepare.append(_add_headers)
        self.app.add_routes(
            [
                web.get("/", self.on_page),
                web.get("/static/{name}", self.on_asset),
                web.get("/ws", self.on_socket),
            ]
        )

    @property
    def address(self) -> str:
        """The page's URL without the token (what the node logs)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    @property
    def url(self) -> str:
        """The page's URL with the token: for the owner's terminal only."""
        return with_token(self.address, self.token)

    @property
    def cookie(self) -> str:
        """The token's cookie; one per port, since cookies do not tell ports apart."""
        return f"aes_dashboard_token_{self.port}"

    # --- access ---------------------------------------------------------------------

    @web.middleware
    async def guard(self, request: web.Request, handler: Any) -> web.StreamResponse:
        if self.site.port != self.port:  # port 0 became a real one
            self.site = Site(self.host, self.port)
        remote = request.remote or "?"
        host = request.headers.get("Host")  # not request.host: that falls back to the socket's
        if not self.site.host_allowed(host):
            self.node._warn(f"refused a request for another Host: {host!r} from {remote}")
            return _refusal(403, "this server does not answer to that Host name")
        origin = request.headers.get("Origin")
        needs_origin = request.method not in SAFE_METHODS or request.path == "/ws"
        if (origin is not None or needs_origin) and not self.site.origin_allowed(origin):
            self.node._warn(f"refused a request from another page: Origin {origin!r} from {remote}")
            return _refusal(403, "only this dashboard's own page may do that")
        from_query = request.query.get("token")
        given = from_query if from_query is not None else request.cookies.get(self.cookie)
        now = time.monotonic()
        if given is not None and self.failures.locked(remote, now):
            return _refusal(429, "too many wrong tokens from this address: wait a minute")
        valid = given is not None and hmac.compare_digest(given.encode(), self.token.encode())
        if given is not None and not valid:
            self.failures.add(remote, now)
            self.node._warn(f"refused a wrong token: {request.path} from {remote}")
            response = _refusal(401, "wrong token: open the URL the dashboard printed")
            response.del_cookie(self.cookie)
            return response
        if not valid and needs_token(self.host):
            self.node._warn(f"refused a request with no valid token: {request.path} from {remote}")
            return _refusal(401, "this dashboard needs its token (?token=…)")
        request[MAY_CONTROL] = valid
        response = await handler(request)
        if valid and from_query is not None and not response.prepared:
            response.set_cookie(self.cookie, self.token, httponly=True, samesite="Strict")
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

    async def on_socket(self, request: web.Request) -> web.StreamResponse:
        if len(self.viewers) + self.opening >= MAX_VIEWERS:
            self.node._warn(f"refused a viewer: already {MAX_VIEWERS} (from {request.remote})")
            return _refusal(503, f"already {MAX_VIEWERS} viewers")
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=1 << 16)
        self.opening += 1
        try:
            await ws.prepare(request)
        finally:
            self.opening -= 1
        may_control = request.get(MAY_CONTROL, False)
        limit = RateLimit()
        with self.node.lock:
            sheet = self.node.view.sheet_message()
        await ws.send_str(json.dumps(sheet))
        await ws.send_str(json.dumps({"type": "access", "control": may_control}))
        self.viewers.add(ws)
        try:
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    if not may_control:
                        answer = _result(False, NO_CONTROL)
                    else:
                        answer = await self.control(message.data, limit)
                    await ws.send_str(json.dumps(answer))
                elif message.type == WSMsgType.BINARY:
                    await ws.send_str(json.dumps(_result(False, "send JSON text, not binary")))
                elif message.type == WSMsgType.ERROR:  # e.g. a message over max_msg_size
                    break
        finally:
            self.viewers.discard(ws)
        return ws

    async def control(self, text: str, limit: RateLimit) -> dict[str, Any]:
        """Check one control message and, if it passes, have the node carry it out."""
        now = time.monotonic()
        if not limit.allow(now):
            return _result(False, "too many control messages: at most 10 a second")
        if not self.controls.allow(now):
            rate = CONTROL_RATE[0]
            return _result(False, f"too many control messages: at most {rate:g} a second in all")
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
        self.node.get_logger().info(f"{names.DASHBOARD_READY} {self.address}")
        if self.print_url:  # the owner's terminal: never the log or /rosout
            print(f"{names.DASHBOARD_READY} {self.url}", flush=True)
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


def _refusal(status: int, why: str) -> web.Response:
    """An HTTP refusal with its reason as the body."""
    return web.Response(status=status, text=f"{status}: {why}")


async def _add_headers(request: web.Request, response: web.StreamResponse) -> None:
    response.headers.update(HEADERS)


def _result(ok: bool, message: str) -> dict[str, Any]:
    return {"type": "result", "ok": ok, "message": message}
