"""Headless Chromium from the system's Debian packages (``chromium``, ``chromium-driver``,
installed by scripts/setup.sh), driven by Selenium: nothing is downloaded at run time."""

from __future__ import annotations

import contextlib
import http.server
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: Where Debian puts the browser and its driver.
CHROMIUM = ("/usr/bin/chromium", "/usr/lib/chromium/chromium")
CHROMEDRIVER = ("/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver")


def _first(paths: tuple[str, ...], name: str) -> str | None:
    return next((p for p in paths if Path(p).exists()), None) or shutil.which(name)


def unavailable() -> str | None:
    """Why a headless Chromium cannot be driven here (None when it can)."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    if _first(CHROMIUM, "chromium") is None:
        return "no chromium (Debian package chromium; scripts/setup.sh installs it as root)"
    if _first(CHROMEDRIVER, "chromedriver") is None:
        return "no chromedriver (Debian package chromium-driver; scripts/setup.sh installs it)"
    return None


def headless_chromium(width: int = 1400, height: int = 900) -> Any:
    """A Selenium WebDriver of the system's Chromium, headless, without a sandbox (it
    runs as root in CI), without background network traffic."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = _first(CHROMIUM, "chromium")
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--disable-background-networking",
        "--disable-extensions",
        "--no-first-run",
        f"--window-size={width},{height}",
    ):
        options.add_argument(arg)
    service = Service(executable_path=_first(CHROMEDRIVER, "chromedriver"))
    return webdriver.Chrome(service=service, options=options)


def page_state(driver: Any) -> dict[str, Any]:
    """The page's ``window.aesDashboard`` (what it received and drew)."""
    return driver.execute_script(
        "const s = window.aesDashboard; return s && {frames: s.frames, draws: s.draws,"
        " drawMs: s.drawMs, drawn: s.drawn, connected: s.connected, n: s.frame && s.frame.n,"
        " results: s.results};"
    )


@contextlib.contextmanager
def page_server(html: str) -> Iterator[str]:
    """Serve ``html`` at ``http://127.0.0.1:<a free port>/`` (any path) from a thread of
    this process until the block ends; yields that URL. A page of another origin than
    the dashboard's, as any web site or local program could put in the user's browser."""
    body = html.encode()

    class Page(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)
