"""The Dask scheduler a sweep runs on: its address and, for ``tls://``, the user's certificates.

A Dask scheduler unpickles what clients and workers send it, so whoever reaches it
runs code on every machine of the cluster. :func:`scheduler` accepts ``tcp://`` (a
warning unless the host is this machine) and ``tls://`` with the three PEM files of
the user's own CA (mutual TLS, ``require_encryption``); docs/studies.md shows both
set-ups.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from aes_ros.sweep.spec import SweepSpecError

#: Option names of the three certificate files, in the order of :class:`TlsFiles`.
TLS_OPTIONS = ("--tls-ca", "--tls-cert", "--tls-key")

PLAIN_WARNING = (
    "warning: --scheduler {address} is plain TCP on another host: anyone who reaches it "
    "runs code here and on every worker (Dask unpickles what it is sent). Use tls:// with "
    "--tls-ca/--tls-cert/--tls-key, or an SSH tunnel to a scheduler on 127.0.0.1 "
    "(docs/studies.md)."
)


@dataclass(frozen=True)
class TlsFiles:
    """PEM files: the CA that signed every member of the cluster, this client's certificate
    and its private key."""

    ca: Path
    cert: Path
    key: Path


@dataclass(frozen=True)
class Scheduler:
    """A Dask scheduler's address (``tcp://HOST:PORT`` or ``tls://HOST:PORT``) and, for
    ``tls://``, the certificates to connect with."""

    address: str
    tls: TlsFiles | None = None

    def __str__(self) -> str:
        return self.address

    def security(self) -> Any:
        """A ``distributed.security.Security`` for the certificates, or None for ``tcp://``."""
        if self.tls is None:
            return None
        from distributed.security import Security

        return Security(
            tls_ca_file=str(self.tls.ca),
            tls_client_cert=str(self.tls.cert),
            tls_client_key=str(self.tls.key),
            require_encryption=True,
        )

    def client(self, timeout: str = "30s") -> Any:
        """A connected ``dask.distributed.Client``; :class:`SweepSpecError` if refused."""
        from dask.distributed import Client

        try:
            return Client(self.address, security=self.security(), timeout=timeout)
        except OSError as exc:  # refused, TLS handshake failed, or timed out
            raise SweepSpecError(f"--scheduler {self.address}: cannot connect: {exc}") from None


def is_loopback(host: str) -> bool:
    """Whether ``host`` (a name or an IP literal) is this machine; names are not resolved."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def scheduler(
    address: str,
    ca: Path | None = None,
    cert: Path | None = None,
    key: Path | None = None,
    warn: Callable[[str], None] = print,
) -> Scheduler:
    """Check a ``--scheduler`` address and its ``--tls-*`` files; the :class:`Scheduler`.

    Raises :class:`SweepSpecError` naming the option when the files are not all three
    given, one is not a readable file, or the address's protocol does not match them.
    Calls ``warn`` when a plain ``tcp://`` scheduler is on another host.
    """
    given = dict(zip(TLS_OPTIONS, (ca, cert, key), strict=True))
    missing = [name for name, path in given.items() if path is None]
    if len(missing) not in (0, 3):
        raise SweepSpecError(
            f"{', '.join(missing)}: TLS needs all three of {', '.join(TLS_OPTIONS)}"
        )
    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in ("tcp", "tls") or not parts.hostname or port is None:
        raise SweepSpecError(f"--scheduler {address!r}: need tcp://HOST:PORT or tls://HOST:PORT")
    if parts.scheme == "tcp":
        if not missing:
            raise SweepSpecError(f"--scheduler {address}: the --tls-* files need a tls:// address")
        if not is_loopback(parts.hostname):
            warn(PLAIN_WARNING.format(address=address))
        return Scheduler(address)
    if missing:
        raise SweepSpecError(f"--scheduler {address}: tls:// needs {', '.join(TLS_OPTIONS)}")
    for name, path in given.items():
        if not Path(path).is_file():
            raise SweepSpecError(f"{name} {path}: no such file")
        try:
            Path(path).open("rb").close()
        except OSError as exc:
            raise SweepSpecError(f"{name} {path}: cannot be read ({exc.strerror})") from None
    return Scheduler(address, TlsFiles(Path(ca), Path(cert), Path(key)))
