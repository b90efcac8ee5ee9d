"""Byte transports of the Mona link: a serial line (termios) and UDP datagrams.

Plain ``os``/``termios``/``socket``, no pyserial: a raw 8N1 line at a standard baud is
all the link needs, and a pseudo-terminal (the tests' stand-in, the firmware in the
loop) opens the same way as a USB serial adapter. Every call is non-blocking; an
``OSError`` (or :class:`LinkDownError`) means the link is gone and its owner reopens it.
"""

from __future__ import annotations

import errno
import os
import socket
import termios
from collections.abc import Iterator

#: Most bytes read from a serial line in one poll.
READ_CHUNK = 4096


class LinkDownError(OSError):
    """The other end hung up (a serial device that disappeared)."""


class SerialPort:
    """A serial line in raw 8N1 mode at ``baud``; reopened by calling :meth:`open` again."""

    def __init__(self, device: str, baud: int) -> None:
        self.device = device
        self.baud = baud
        self.fd: int | None = None
        self.opened_path = ""  #: the device ``device`` led to when it opened (symlinks followed)

    @property
    def is_open(self) -> bool:
        return self.fd is not None

    def open(self) -> None:
        """Open and configure the device; ``OSError`` says why it cannot be."""
        self.close()
        path = os.path.realpath(self.device)
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            if not os.isatty(fd):
                raise OSError(errno.ENOTTY, "not a serial device (a terminal)", self.device)
            attrs = termios.tcgetattr(fd)
            speed = getattr(termios, f"B{self.baud}")
            attrs[0] = 0  # iflag: no break, parity, CR/NL or flow-control processing
            attrs[1] = 0  # oflag: bytes go out unchanged
            attrs[2] = termios.CS8 | termios.CREAD | termios.CLOCAL  # 8N1, no modem control
            attrs[3] = 0  # lflag: no echo, no line editing, no signals
            attrs[4] = attrs[5] = speed
            # VMIN 1: an empty non-blocking read is EAGAIN, so a read of 0 bytes is a hangup
            attrs[6][termios.VMIN], attrs[6][termios.VTIME] = 1, 0
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
            termios.tcflush(fd, termios.TCIOFLUSH)  # bytes from before this open
        except BaseException:
            os.close(fd)
            raise
        self.fd = fd
        self.opened_path = path

    def moved_to(self) -> str | None:
        """Where ``device`` now leads if the port is open and it leads elsewhere (a
        symlink moved to another device: a ``/dev/serial/by-id`` link after a replug, the
        firmware loop's link to a restarted MCU), so the open one may be another robot's,
        or nobody's; else None."""
        if self.fd is None:
            return None
        path = os.path.realpath(self.device)
        return path if path != self.opened_path else None

    def close(self) -> None:
        if self.fd is not None:
            fd, self.fd = self.fd, None
            try:
                os.close(fd)
            except OSError:
                pass

    def read(self) -> bytes:
        """The bytes waiting (b"" if none); :class:`LinkDownError` or ``OSError`` if gone."""
        if self.fd is None:
            raise LinkDownError(errno.EBADF, "not open", self.device)
        try:
            data = os.read(self.fd, READ_CHUNK)
        except BlockingIOError:
            return b""
        if not data:
            raise LinkDownError(errno.EIO, "the device hung up", self.device)
        return data

    def write(self, data: bytes) -> None:
        """Send ``data`` whole; ``OSError`` if the line is gone or stays full."""
        if self.fd is None:
            raise LinkDownError(errno.EBADF, "not open", self.device)
        view = memoryview(data)
        while view:
            try:
                view = view[os.write(self.fd, view) :]
            except BlockingIOError:
                # kilobytes queued at 11.5 kB/s: nobody reads the other end; never block
                raise LinkDownError(
                    errno.EAGAIN, "output full: nothing reads it", self.device
                ) from None


class UdpHub:
    """The driver's one UDP socket for every robot on Wi-Fi (``port`` 0: any free port).

    A robot answers to the address its frames came from (docs/mona_protocol.md), so a
    firewall needs one port open. Datagrams from addresses not in ``robots`` are
    counted in :attr:`strangers` and dropped.
    """

    def __init__(self, port: int = 0, host: str = "0.0.0.0") -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setblocking(False)
            self.sock.bind((host, port))
        except OSError:
            self.sock.close()
            raise
        self.strangers = 0
        self.last_stranger: tuple[str, int] | None = None

    @property
    def port(self) -> int:
        return self.sock.getsockname()[1]

    def send(self, data: bytes, address: tuple[str, int]) -> None:
        self.sock.sendto(data, address)

    def receive(self, known: set[tuple[str, int]]) -> Iterator[tuple[tuple[str, int], bytes]]:
        """Every datagram waiting from a known address; strangers are counted."""
        while True:
            try:
                data, address = self.sock.recvfrom(2048)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionRefusedError:
                continue  # an ICMP "port unreachable" of an earlier send: the robot is off
            address = (address[0], address[1])
            if address not in known:
                self.strangers += 1
                self.last_stranger = address
                continue
            yield address, data

    def close(self) -> None:
        self.sock.close()


class UdpPort:
    """One robot's end of the :class:`UdpHub`: always open."""

    is_open = True

    def __init__(self, hub: UdpHub, address: tuple[str, int]) -> None:
        self.hub = hub
        self.address = address

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def write(self, data: bytes) -> None:
        self.hub.send(data, self.address)
