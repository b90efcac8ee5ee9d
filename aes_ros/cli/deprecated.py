"""Old flag spellings that keep working for one release, with a warning on stderr.

An old spelling parses to the ``dest`` of its new flag, is hidden from ``--help`` and
prints one line such as ``aes-swarm sweep: --mc is deprecated; use --runs``::

    p.add_argument("--runs", type=int, default=10, help="Monte-Carlo runs")
    add_deprecated(p, "--mc", "--runs")
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any


class DeprecatedFlag(argparse.Action):
    """Store the value under the new flag's ``dest`` and warn once per use."""

    def __init__(self, option_strings: list[str], dest: str, *, new: str, prog: str, **kw: Any):
        super().__init__(option_strings, dest, help=argparse.SUPPRESS, **kw)
        self.new = new
        self.prog = prog

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        print(f"{self.prog}: {option_string} is deprecated; use {self.new}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_deprecated(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    old: str,
    new: str,
    *,
    prog: str | None = None,
) -> argparse.Action:
    """Let ``old`` stand for the already added flag ``new``: same ``dest``, ``type``,
    ``nargs`` and ``metavar``; hidden from ``--help``; the warning names ``prog``
    (default: the parser's)."""
    target = next(a for a in parser._actions if new in a.option_strings)
    return parser.add_argument(
        old,
        action=DeprecatedFlag,
        dest=target.dest,
        new=new,
        prog=prog or getattr(parser, "prog", "aes-swarm"),
        type=target.type,
        nargs=target.nargs,
        metavar=target.metavar,
        default=argparse.SUPPRESS,
    )
