"""The dashboard's access token: made up or taken from the environment, checked, and put
in the dashboard's URL (pure; the launch and the dashboard node share it).

The token is at least :data:`MIN_TOKEN_CHARS` characters; one is made up
(:func:`new_token`, 192 bits) unless :data:`TOKEN_VARIABLE` or a 0600 file named by
:data:`TOKEN_FILE_VARIABLE` gives one (:func:`given_token`). It never goes on a
command line, where every user of the machine reads it (``ps``).
"""

from __future__ import annotations

import os
import secrets
import stat
from collections.abc import Mapping
from urllib.parse import quote

#: The environment variable holding the token, and the one naming a file that holds it.
TOKEN_VARIABLE = "AES_DASHBOARD_TOKEN"
TOKEN_FILE_VARIABLE = "AES_DASHBOARD_TOKEN_FILE"
MIN_TOKEN_CHARS = 16
#: Random bytes of a made-up token (192 bits; 32 URL-safe characters).
TOKEN_BYTES = 24


class TokenError(ValueError):
    """A token that is refused; the text says why (never the token itself)."""


def new_token() -> str:
    """A fresh random token of :data:`TOKEN_BYTES` bytes, URL-safe."""
    return secrets.token_urlsafe(TOKEN_BYTES)


def check_token(token: str, source: str) -> str:
    """``token`` if it is usable: at least MIN_TOKEN_CHARS visible ASCII characters."""
    if len(token) < MIN_TOKEN_CHARS:
        raise TokenError(
            f"{source}: a token of {len(token)} characters; at least {MIN_TOKEN_CHARS} "
            f"(e.g. python -c 'import secrets; print(secrets.token_urlsafe({TOKEN_BYTES}))')"
        )
    if not all(33 <= ord(c) <= 126 for c in token):
        raise TokenError(f"{source}: the token may hold visible ASCII characters only")
    return token


def read_token_file(path: str | os.PathLike) -> str:
    """The token in the file ``path`` (one line), which must be a regular file of this
    user that nobody else may read or write (``chmod 600``)."""
    source = f"token file {path}"
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as exc:
        raise TokenError(f"{source}: {exc.strerror}") from None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise TokenError(f"{source}: not a regular file")
        if info.st_uid != os.geteuid():
            raise TokenError(f"{source}: owned by uid {info.st_uid}, not by this user")
        if info.st_mode & 0o077:
            mode = stat.S_IMODE(info.st_mode)
            raise TokenError(f"{source}: mode {mode:o}; others may read it (chmod 600)")
        text = fh.read(4096).decode("ascii", errors="replace")
    return check_token(text.strip(), source)


def given_token(env: Mapping[str, str]) -> str | None:
    """The token the environment gives (:data:`TOKEN_VARIABLE`, else the file named by
    :data:`TOKEN_FILE_VARIABLE`); None if neither is set. TokenError if it is unusable."""
    if env.get(TOKEN_VARIABLE):
        return check_token(env[TOKEN_VARIABLE], TOKEN_VARIABLE)
    if env.get(TOKEN_FILE_VARIABLE):
        return read_token_file(env[TOKEN_FILE_VARIABLE])
    return None


def with_token(url: str, token: str) -> str:
    """``url`` (the dashboard's address, ending in ``/``) with ``?token=…``."""
    return f"{url}?token={quote(token, safe='')}"
