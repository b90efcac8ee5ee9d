"""Who may use the dashboard, tried against the real aiohttp app (``Dashboard.app``) over
real sockets with aiohttp's test client; the ROS node is a stand-in that records what
it is asked to do (the system tests use the real one).

Foreign ``Origin`` or ``Host`` → 403 before the WebSocket opens; without the token a
loopback viewer gets the sheet but no control; the 33rd viewer gets 503; an oversized
frame closes that socket only; binary frames get an error; wrong tokens lock their
address out (429) and are logged once; the global control rate; the security headers;
the token's length, file mode and the CLI's refusal of ``--token``.
"""

from __future__ import annotations

import asyncio
import base64
import concurrent.futures
import json
import os
import threading
from collections.abc import Awaitable, Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import aiohttp
import pytest
from aiohttp.test_utils import TestClient, TestServer

from aes_ros import cli
from aes_ros.ros import dashboard_token
from aes_ros.ros.dashboard_token import TokenError
from aes_ros.ros.node_tools import ThrottledWarnings
from dashboard_node import server
from dashboard_node.access import Failures, Site
from dashboard_node.server import HEADERS, MAX_VIEWERS, Dashboard

TOKEN = "a-token-of-the-owner-0123456789"
ENABLE = json.dumps({"type": "enable", "enabled": False})


class Logger:
    def __init__(self) -> None:
        self.warnings: list[str] = []
        self.infos: list[str] = []

    def warning(self, text: str) -> None:
        self.warnings.append(text)

    def info(self, text: str) -> None:
        self.infos.append(text)


class StandIn:
    """What the server needs of a :class:`dashboard_node.node.DashboardNode`."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.view = SimpleNamespace(sheet_message=lambda: {"type": "sheet", "n": 4})
        self.logger = Logger()
        self._warn = ThrottledWarnings(self.logger)
        self.submitted: list[Any] = []

    def get_logger(self) -> Logger:
        return self.logger

    def submit(self, control: Any) -> concurrent.futures.Future:
        self.submitted.append(control)
        future: concurrent.futures.Future = concurrent.futures.Future()
        future.set_result((True, "done"))
        return future

    def accepted(self, control: Any) -> None:
        pass


Test = Callable[[TestClient, Dashboard], Awaitable[None]]


def serve(test: Test, host: str = "127.0.0.1") -> StandIn:
    """Run ``test`` against a Dashboard bound (as far as it knows) to ``host``, really
    listening on 127.0.0.1 at a free port; returns the stand-in node."""
    node = StandIn()

    async def main() -> None:
        dashboard = Dashboard(node, host, 0, TOKEN)  # type: ignore[arg-type]
        async with TestClient(TestServer(dashboard.app, host="127.0.0.1")) as client:
            dashboard.port = client.port
            await test(client, dashboard)

    asyncio.run(main())
    return node


def origin(client: TestClient) -> str:
    return f"http://127.0.0.1:{client.port}"


async def result_of(ws: aiohttp.ClientWebSocketResponse, text: str) -> dict[str, Any]:
    await ws.send_str(text)
    while True:
        message = json.loads((await ws.receive(timeout=5)).data)
        if message["type"] == "result":
            return message


async def opening(ws: aiohttp.ClientWebSocketResponse) -> list[dict[str, Any]]:
    """The two messages a viewer gets first: the sheet and its access."""
    return [json.loads((await ws.receive(timeout=5)).data) for _ in range(2)]


# --- Origin and Host ------------------------------------------------------------------


@pytest.mark.parametrize(
    "page",
    [
        "http://127.0.0.1:{other}",  # another server on this machine
        "http://localhost:{other}",
        "https://127.0.0.1:{port}",
        "http://evil.example",
        "http://evil.example:{port}",  # a DNS-rebound name
        "null",
        None,  # not a browser: it must say where it comes from
    ],
)
def test_a_foreign_origin_cannot_open_the_websocket(page: str | None) -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        given = page and page.format(port=client.port, other=client.port + 1)
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await client.ws_connect(f"/ws?token={TOKEN}", origin=given)
        assert refused.value.status == 403
        assert not dashboard.viewers

    node = serve(test)
    assert node.submitted == []
    assert any("another page" in w for w in node.logger.warnings)


def test_a_foreign_host_is_refused() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        port = client.port
        for host in (f"evil.example:{port}", f"127.0.0.1:{port + 1}", "127.0.0.1", ""):
            response = await client.get(f"/?token={TOKEN}", headers={"Host": host})
            assert response.status == 403, host
            assert "Host" in await response.text()
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            evil = f"evil.example:{port}"
            await client.ws_connect("/ws", origin=f"http://{evil}", headers={"Host": evil})
        assert refused.value.status == 403
        # no Host header at all (HTTP/1.0)
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(b"GET / HTTP/1.0\r\n\r\n")
        assert (await reader.readline()).startswith(b"HTTP/1.0 403")
        writer.close()
        for name in ("127.0.0.1", "localhost", "[::1]", "LOCALHOST"):
            host = f"{name}:{port}"
            response = await client.get("/", headers={"Host": host})
            assert response.status == 200, host

    serve(test)


def test_the_host_and_origin_rules() -> None:
    here = Site("127.0.0.1", 8080)
    assert here.host_allowed("localhost:8080") and here.origin_allowed("http://[::1]:8080")
    assert not here.host_allowed("10.0.0.5:8080") and not here.origin_allowed("http://x:8080/")
    anywhere = Site("0.0.0.0", 8080)
    assert anywhere.host_allowed("10.0.0.5:8080") and anywhere.host_allowed("[fe80::1]:8080")
    assert not anywhere.host_allowed("attacker.example:8080")
    assert not anywhere.host_allowed("10.0.0.5:8081") and not anywhere.host_allowed("fe80::1:8080")
    one = Site("10.0.0.5", 80)
    assert one.host_allowed("10.0.0.5") and one.host_allowed("10.0.0.5:80")
    assert not one.host_allowed("10.0.0.6:80") and not one.host_allowed("127.0.0.1:80")


# --- the token --------------------------------------------------------------------


def test_without_the_token_a_loopback_viewer_watches_but_cannot_steer() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        page = await client.get("/")
        assert page.status == 200 and "aes-swarm" in await page.text()
        async with client.ws_connect("/ws", origin=origin(client)) as ws:
            sheet, may = await opening(ws)
            assert sheet == {"type": "sheet", "n": 4}
            assert may == {"type": "access", "control": False}
            answer = await result_of(ws, ENABLE)
            assert not answer["ok"] and "no token" in answer["message"]
        assert dashboard.node.submitted == []
        # the URL the dashboard printed: the token on the WebSocket's URL, or in the
        # cookie the page got with it
        async with client.ws_connect(f"/ws?token={TOKEN}", origin=origin(client)) as ws:
            assert (await opening(ws))[1]["control"] is True
            assert (await result_of(ws, ENABLE))["ok"]
        assert (await client.get(f"/?token={TOKEN}")).status == 200
        async with client.ws_connect("/ws", origin=origin(client)) as ws:
            assert (await opening(ws))[1]["control"] is True
            assert (await result_of(ws, ENABLE))["ok"]

    node = serve(test)
    assert len(node.submitted) == 2


def test_off_loopback_everything_needs_the_token() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        for path in ("/", "/static/app.js", "/nowhere"):
            assert (await client.get(path)).status == 401, path
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await client.ws_connect("/ws", origin=origin(client))
        assert refused.value.status == 401
        assert (await client.get(f"/?token={TOKEN}")).status == 200  # sets the cookie
        assert (await client.get("/static/app.js")).status == 200
        async with client.ws_connect("/ws", origin=origin(client)) as ws:
            assert (await opening(ws))[1]["control"] is True

    node = serve(test, host="0.0.0.0")
    assert any("no valid token" in w for w in node.logger.warnings)


def test_wrong_tokens_lock_their_address_out_and_are_logged_once() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        guesses = [f"/?token=guess-{k:02d}-xxxxxxxxxx" for k in range(20)]
        statuses = [(await client.get(guess)).status for guess in guesses]
        assert statuses[:5] == [401] * 5 and set(statuses[5:]) == {429}
        # locked out: the right token too, on HTTP and on the WebSocket
        assert (await client.get(f"/?token={TOKEN}")).status == 429
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await client.ws_connect(f"/ws?token={TOKEN}", origin=origin(client))
        assert refused.value.status == 429
        # viewing without a token goes on (loopback), and the lockout ends
        assert (await client.get("/")).status == 200
        dashboard.failures = Failures(lockout=0.0)
        assert (await client.get(f"/?token={TOKEN}")).status == 200

    node = serve(test)
    refused = [w for w in node.logger.warnings if "wrong token" in w]
    assert len(refused) == 1, node.logger.warnings  # throttled: one line for 20 tries
    assert not any(TOKEN in w for w in node.logger.warnings)


def test_a_stale_cookie_is_dropped() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        old = {dashboard.cookie: "an-old-token-of-a-restart"}
        client.session.cookie_jar.update_cookies(old, response_url=client.make_url("/"))
        response = await client.get("/")
        assert response.status == 401
        assert response.cookies[dashboard.cookie].value == ""  # deleted
        assert (await client.get("/")).status == 200  # a viewer now

    serve(test)


def test_made_up_tokens_have_128_bits_and_short_ones_are_refused(tmp_path: Path) -> None:
    made = {dashboard_token.new_token() for _ in range(100)}
    assert len(made) == 100
    assert all(len(base64.urlsafe_b64decode(t + "==")) * 8 >= 128 for t in made)
    assert Dashboard(StandIn(), "127.0.0.1", 0).token not in made  # type: ignore[arg-type]
    with pytest.raises(TokenError, match="15 characters; at least 16"):
        dashboard_token.given_token({dashboard_token.TOKEN_VARIABLE: "x" * 15})
    assert dashboard_token.given_token({dashboard_token.TOKEN_VARIABLE: "x" * 16}) == "x" * 16
    with pytest.raises(TokenError, match="visible ASCII"):
        dashboard_token.check_token("x" * 16 + " y", "test")
    assert dashboard_token.given_token({}) is None


def test_a_token_file_must_be_private(tmp_path: Path) -> None:
    path = tmp_path / "token"
    path.write_text(TOKEN + "\n")
    path.chmod(0o644)
    with pytest.raises(TokenError, match="mode 644; others may read it"):
        dashboard_token.given_token({dashboard_token.TOKEN_FILE_VARIABLE: str(path)})
    path.chmod(0o600)
    assert dashboard_token.given_token({dashboard_token.TOKEN_FILE_VARIABLE: str(path)}) == TOKEN
    link = tmp_path / "link"
    link.symlink_to(path)
    with pytest.raises(TokenError, match="token file"):
        dashboard_token.read_token_file(link)
    with pytest.raises(TokenError, match="No such file"):
        dashboard_token.read_token_file(tmp_path / "missing")


def test_the_cli_takes_no_token_on_its_command_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture, tmp_path: Path
) -> None:
    assert cli.main(["dashboard", "--token", TOKEN]) == 2
    err = capsys.readouterr().err
    assert "--token" in err and dashboard_token.TOKEN_VARIABLE in err and "--token-file" in err
    monkeypatch.setenv(dashboard_token.TOKEN_VARIABLE, "short")
    assert cli.main(["dashboard"]) == 2
    assert "5 characters; at least 16" in capsys.readouterr().err
    monkeypatch.delenv(dashboard_token.TOKEN_VARIABLE)
    loose = tmp_path / "token"
    loose.write_text(TOKEN)
    loose.chmod(0o640)
    assert cli.main(["dashboard", "--token-file", str(loose)]) == 2
    assert "chmod 600" in capsys.readouterr().err
    monkeypatch.setenv(dashboard_token.TOKEN_VARIABLE, "short")
    launch = ["launch", "--robots", "4", "--dashboard", "0", "--out", str(tmp_path / "out")]
    assert cli.main(launch) == 2
    assert "at least 16" in capsys.readouterr().err


# --- viewers and their messages -----------------------------------------------------


def test_the_33rd_viewer_is_refused() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        here = origin(client)
        viewers = [await client.ws_connect("/ws", origin=here) for _ in range(MAX_VIEWERS)]
        with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
            await client.ws_connect("/ws", origin=origin(client))
        assert refused.value.status == 503
        await viewers.pop().close()
        for _ in range(500):  # until the server's side of it has closed too
            if len(dashboard.viewers) < MAX_VIEWERS:
                break
            await asyncio.sleep(0.01)
        viewers.append(await client.ws_connect("/ws", origin=origin(client)))
        assert len(dashboard.viewers) == MAX_VIEWERS
        for ws in viewers:
            await ws.close()

    serve(test)


def test_an_oversized_frame_closes_that_socket_and_the_others_go_on() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        url = f"/ws?token={TOKEN}"
        async with (
            client.ws_connect(url, origin=origin(client)) as big,
            client.ws_connect(url, origin=origin(client)) as other,
        ):
            await opening(big)
            await opening(other)
            await big.send_str("x" * (1 << 17))
            closed = await big.receive(timeout=5)
            assert closed.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
            assert big.close_code == aiohttp.WSCloseCode.MESSAGE_TOO_BIG
            assert (await result_of(other, ENABLE))["ok"]
        async with client.ws_connect(url, origin=origin(client)) as later:
            assert (await opening(later))[0]["type"] == "sheet"

    node = serve(test)
    assert len(node.submitted) == 1


def test_binary_frames_are_answered_with_an_error() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        async with client.ws_connect(f"/ws?token={TOKEN}", origin=origin(client)) as ws:
            await opening(ws)
            await ws.send_bytes(ENABLE.encode())
            answer = json.loads((await ws.receive(timeout=5)).data)
            assert answer["type"] == "result" and not answer["ok"]
            assert answer["message"] == "send JSON text, not binary"
            assert (await result_of(ws, ENABLE))["ok"]  # still open

    node = serve(test)
    assert len(node.submitted) == 1


def test_all_viewers_together_are_rate_limited(monkeypatch: pytest.MonkeyPatch) -> None:
    # the server's clock stands still: no refill, however slowly this machine runs
    monkeypatch.setattr(server, "time", SimpleNamespace(monotonic=lambda: 1000.0))

    async def test(client: TestClient, dashboard: Dashboard) -> None:
        url = f"/ws?token={TOKEN}"
        sockets = [await client.ws_connect(url, origin=origin(client)) for _ in range(4)]
        for ws in sockets:
            await opening(ws)
        # 4 × 15: within each viewer's own burst of 20, beyond the global one of 40
        answers = [await result_of(ws, ENABLE) for _ in range(15) for ws in sockets]
        refused = [a["message"] for a in answers if not a["ok"]]
        assert len(refused) == 20 and all("in all" in m for m in refused), refused
        for ws in sockets:
            await ws.close()

    node = serve(test)
    assert len(node.submitted) == 40


# --- headers ----------------------------------------------------------------------


def test_every_response_carries_the_security_headers() -> None:
    async def test(client: TestClient, dashboard: Dashboard) -> None:
        responses = [
            await client.get("/"),
            await client.get("/static/app.js"),
            await client.get("/static/secrets.txt"),  # 404
            await client.get("/", headers={"Host": "evil.example"}),  # 403
            await client.get("/?token=wrong-token-0123456789"),  # 401
        ]
        assert [r.status for r in responses] == [200, 200, 404, 403, 401]
        for response in responses:
            for name, value in HEADERS.items():
                assert response.headers.get(name) == value, (response.status, name)
        csp = responses[0].headers["Content-Security-Policy"]
        assert "frame-ancestors 'none'" in csp and "default-src 'self'" in csp
        assert responses[0].headers["X-Frame-Options"] == "DENY"
        assert responses[0].headers["Referrer-Policy"] == "no-referrer"

    serve(test)


def test_the_ready_line_has_no_token() -> None:
    dashboard = Dashboard(StandIn(), "127.0.0.1", 8080, TOKEN)  # type: ignore[arg-type]
    assert dashboard.address == "http://127.0.0.1:8080/"
    assert dashboard.url == f"http://127.0.0.1:8080/?token={TOKEN}"
    assert os.environ.get(dashboard_token.TOKEN_VARIABLE) != TOKEN
