"""Who may use the dashboard: the ``Host`` and ``Origin`` it answers, and how
often refusals and controls may come (pure: no aiohttp, no rclpy).

- The token: :mod:`aes_ros.ros.dashboard_token` (the launch hands it over too).
- :class:`Site` says which ``Host`` headers and ``Origin`` values a server bound to one
  address and port answers: a page from any other origin (another port included) or a
  DNS-rebound name gets HTTP 403.
- :class:`Failures` counts wrong tokens per remote address and locks that address out
  for a while; the control rate of all viewers together is a
  :class:`dashboard_node.controls.RateLimit` of :data:`CONTROL_RATE`.

docs/dashboard.md has the table of who can do what.
"""

from __future__ import annotations

import ipaddress
import socket
from collections import deque

LOOPBACK = ("127.0.0.1", "localhost", "::1")
WILDCARD = ("0.0.0.0", "::", "")
#: At most this many viewers (WebSockets) at once; the next one gets HTTP 503.
MAX_VIEWERS = 32
#: Control messages per second of all viewers together, and the burst.
CONTROL_RATE = (20.0, 40)


def is_loopback(host: str) -> bool:
    """True if ``host`` (a bind address) is reachable from this machine only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _host_port(name: str, port: int) -> set[str]:
    """The ``Host`` header values that name ``name`` at ``port`` (lower case)."""
    name = name.lower()
    if ":" in name and not name.startswith("["):
        name = f"[{name}]"  # an IPv6 address
    values = {f"{name}:{port}"}
    if port == 80:
        values.add(name)
    return values


class Site:
    """What a server bound to ``host``:``port`` answers.

    Host headers: the bound address; for a loopback bind also ``127.0.0.1``,
    ``localhost`` and ``[::1]``; for a wildcard bind (``0.0.0.0``, ``::``) any IP
    address (a DNS-rebound page names the attacker's domain, not an address), the
    loopback names and this machine's host names; always with the port. An
    ``Origin`` is accepted only as ``http://`` plus one of those hosts: a page from
    another port, scheme or name is foreign.
    """

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.wildcard = host in WILDCARD
        names = {host}
        if is_loopback(host) or self.wildcard:
            names.update(LOOPBACK)
        if self.wildcard or not is_loopback(host):
            names.update(_machine_names())
        names.discard("")
        self.hosts = frozenset(v for name in names for v in _host_port(name, port))

    def host_allowed(self, value: str | None) -> bool:
        """True if a request's ``Host`` header names this server."""
        if not value:
            return False
        value = value.lower()
        if value in self.hosts:
            return True
        if not self.wildcard:
            return False
        name, _, port = value.rpartition(":")
        if port != str(self.port) or not name:
            return False
        try:
            ipaddress.ip_address(name.strip("[]"))
        except ValueError:
            return False
        return name.startswith("[") == (":" in name)  # IPv6 in brackets, IPv4 without

    def origin_allowed(self, value: str | None) -> bool:
        """True if ``Origin`` is this server's own (what its page sends)."""
        if not value:
            return False
        scheme, sep, rest = value.lower().partition("://")
        return scheme == "http" and bool(sep) and "/" not in rest and self.host_allowed(rest)


def _machine_names() -> set[str]:
    """This machine's host names (what a user on another machine types)."""
    found = set()
    for get in (socket.gethostname, socket.getfqdn):
        try:
            found.add(get().lower())
        except OSError:
            pass
    return found


class Failures:
    """Wrong tokens per remote address: after ``limit`` within ``window`` s that
    address is locked out (HTTP 429) until ``lockout`` s after its last failure.
    At most ``remotes`` addresses are remembered (the oldest forgotten first).

    >>> failures = Failures(limit=2)
    >>> failures.add("10.0.0.7", now=0.0); failures.add("10.0.0.7", now=1.0)
    >>> failures.locked("10.0.0.7", now=2.0), failures.locked("10.0.0.8", now=2.0)
    (True, False)
    """

    def __init__(
        self, limit: int = 5, window: float = 60.0, lockout: float = 60.0, remotes: int = 4096
    ) -> None:
        self.limit, self.window, self.lockout, self.remotes = limit, window, lockout, remotes
        self._times: dict[str, deque[float]] = {}

    def add(self, remote: str, now: float) -> None:
        times = self._times.pop(remote, None) or deque(maxlen=self.limit)
        times.append(now)
        self._times[remote] = times  # the most recent last
        while len(self._times) > self.remotes:
            del self._times[next(iter(self._times))]

    def locked(self, remote: str, now: float) -> bool:
        times = self._times.get(remote)
        if not times or len(times) < self.limit:
            return False
        return times[-1] - times[0] <= self.window and now - times[-1] < self.lockout
