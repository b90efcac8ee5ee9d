"""Every ``aes-swarm …`` and ``python bench/….py …`` command in README.md and docs/ parses,
and every ROS parameter a command sets (``-p name:=…``, ``ros2 param set``) exists.

Commands are taken from fenced blocks and from inline code spans. Each ``aes-swarm``
command is given to the real parser (nothing runs); each benchmark command to its
script's own parser in one subprocess that stops every script right after parsing.
An unknown or deprecated flag, a missing argument or a value the parser refuses fails
with the file and the line. What a command may hold besides plain words:

- ``\\`` continues a line, ``# …`` is a comment, ``&&``, ``;``, ``|`` and redirections
  end a command;
- a placeholder (``<…>``, ``HOST``, ``DIR``, ``$VAR``) stands for a value: it is
  replaced by one the parser takes, when one exists;
- a synopsis (``[--flag X]``, ``{a,b}``) or a command with ``…`` for the elided rest
  is checked flag by flag: each must be an option of its (sub)command;
- a listing (``aes-swarm simulate   what it does``: two spaces after the subcommand)
  only names a subcommand.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import itertools
import json
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from aes_ros.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
PROGRAMS = ("aes-swarm", ".venv/bin/aes-swarm")
PYTHONS = ("python", "python3", ".venv/bin/python", ".venv/bin/python3")
BENCH = re.compile(r"^(\./)?bench/\w+\.py$")
ELISIONS = ("…", "...")
#: Tokens that end one shell command (shlex with punctuation_chars).
SEPARATORS = {"&&", "||", ";", "|", "&", ">", ">>", "<", ">&", "&>", "2>", "2>&1"}
#: What ``<N>`` becomes before the line is split into words.
HOLE = "__PLACEHOLDER__"
PLACEHOLDER = re.compile(rf"{HOLE}|^[A-Z][A-Z0-9_]*(:[A-Z0-9_]+)?$|\$|…")


@dataclass(frozen=True)
class Command:
    """One ``aes-swarm`` command of a document."""

    path: Path
    line: int
    text: str
    argv: tuple[str, ...]
    kind: str  # "parse", "flags" or "listing"
    program: str = "aes-swarm"  # or the benchmark script, e.g. "bench/bench_ros.py"

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def fenced_lines(text: str) -> list[tuple[int, str]]:
    """The lines inside fenced code blocks, with their 1-based line numbers; continued
    lines (``\\``) joined onto the first."""
    out: list[tuple[int, str]] = []
    inside = False
    pending: tuple[int, str] | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        if line.lstrip().startswith("```"):
            inside = not inside
            pending = None
            continue
        if not inside:
            continue
        if pending is not None:
            number, line = pending[0], pending[1] + " " + line.strip()
            pending = None
        if line.rstrip().endswith("\\"):
            pending = (number, line.rstrip()[:-1])
            continue
        out.append((number, line))
    return out


def inline_spans(text: str) -> list[tuple[int, str]]:
    """The inline code spans outside fenced blocks, with the line each starts on (a span
    may run over a line break inside its paragraph)."""
    prose = re.sub(r"^\s*```.*?^\s*```", lambda m: "\n" * m.group().count("\n"), text,
                   flags=re.M | re.S)  # fmt: skip
    return [
        (prose.count("\n", 0, m.start()) + 1, " ".join(m.group(1).split()))
        for m in re.finditer(r"(?<!`)`([^`]+)`(?!`)", prose)
    ]


def _words(line: str) -> list[str]:
    lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    lexer.commenters = "#"
    try:
        return list(lexer)
    except ValueError:  # an unbalanced quote in prose
        return line.split()


def _command(
    path: Path, number: int, body: str, words: list[str], start: int, inline: bool
) -> Command:
    """The command whose program is ``words[start]``; an inline one (often a fragment
    such as ```aes-swarm launch --record```) is checked flag by flag."""
    program = words[start]
    argv: list[str] = []
    for w in words[start + 1 :]:
        if w in SEPARATORS:
            break
        argv.append(w)
    if argv and argv[-1].isdigit() and len(argv) < len(words) - start - 1:
        argv.pop()  # the "2" of "2>&1"
    rest = body.split(program, 1)[1]
    if re.match(r"\s+[a-z]+\s{2,}[^-\s#]", rest):
        kind = "listing"
    elif inline or any(w in ELISIONS or w.startswith(("[", "{")) for w in argv) or "[--" in rest:
        kind = "flags"  # a synopsis: "|" is an alternative there, not a pipe
        argv = rest.split("#", 1)[0].replace("|", " ").split()
    else:
        kind = "parse"
    if program in PROGRAMS:
        return Command(path, number, body, tuple(argv), kind)
    return Command(path, number, body, tuple(argv), kind, program.removeprefix("./"))


def commands_of(path: Path) -> list[Command]:
    """Every ``aes-swarm`` and benchmark command in the code of ``path``."""
    text = path.read_text()
    found = []
    spans = [(n, line, False) for n, line in fenced_lines(text)]
    spans += [(n, line, True) for n, line in inline_spans(text)]
    for number, line, inline in spans:
        body = line.strip().removeprefix("$ ")
        words = _words(re.sub(r"<[^<>\s]+>", HOLE, body))
        for start, word in enumerate(words):
            if word in PROGRAMS:
                found.append(_command(path, number, body, words, start, inline))
            elif word in PYTHONS and start + 1 < len(words) and BENCH.match(words[start + 1]):
                found.append(_command(path, number, body, words, start + 1, inline))
    return sorted(found, key=lambda c: c.line)


ALL = [c for path in DOCS for c in commands_of(path)]


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (action,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def _visible_options(sub: argparse.ArgumentParser) -> set[str]:
    return {s for a in sub._actions if a.help is not argparse.SUPPRESS for s in a.option_strings}


def _candidates(sub: argparse.ArgumentParser, argv: list[str], i: int) -> list[str]:
    """Values that may stand for the placeholder ``argv[i]``."""
    by_flag = {s: a for a in sub._actions for s in a.option_strings}
    action = by_flag.get(argv[i - 1]) if i > 0 else None
    if action is not None and action.choices:
        return [str(next(iter(action.choices)))]
    values = ["1", "1,1", "placeholder", "640x480", "127.0.0.1:8786"]
    for a in sub._actions:
        if not a.option_strings and a.choices:
            values += [str(c) for c in a.choices]
    return values


def _parse(parser: argparse.ArgumentParser, argv: list[str]) -> str | None:
    """The parser's complaint about ``argv`` (its stderr), or None if it parses."""
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            parser.parse_args(argv)
        except SystemExit as exc:
            if exc.code not in (0, None):
                return err.getvalue().strip() or f"exit {exc.code}"
    if "deprecat" in err.getvalue().lower():
        return err.getvalue().strip()
    return None


#: Runs in a subprocess: each benchmark script in turn, stopped right after its parser ran.
#: stdin: a JSON list of [script, argv]; last stdout line: RESULTS + one JSON result each.
RUNNER = r"""
import argparse, contextlib, io, json, runpy, sys

class Parsed(Exception):
    pass

original = argparse.ArgumentParser.parse_args
seen = {}

def parse_args(self, args=None, namespace=None):
    seen["options"] = sorted(
        s for a in self._actions if a.help is not argparse.SUPPRESS for s in a.option_strings
    )
    original(self, args, namespace)
    raise Parsed

argparse.ArgumentParser.parse_args = parse_args
results = []
for script, argv in json.load(sys.stdin):
    seen.clear()
    error = None
    err = io.StringIO()
    if "parse_args(" not in open(script).read():
        results.append({"options": None, "error": "no argparse parser"})
        continue
    sys.argv = [script, *argv]
    sys.path.insert(0, script.rsplit("/", 1)[0])  # as python puts a script's directory
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            runpy.run_path(script, run_name="__main__")
            error = "the script ran without parsing its arguments"
        except Parsed:
            pass
        except SystemExit as exc:
            if exc.code not in (0, None):
                error = err.getvalue().strip() or f"exit {exc.code}"
        except BaseException as exc:
            error = f"{type(exc).__name__}: {exc}"
    if error is None and "deprecat" in err.getvalue().lower():
        error = err.getvalue().strip()
    results.append({"options": seen.get("options"), "error": error})
print("RESULTS" + json.dumps(results))
"""


def _bench_argv(command: Command) -> tuple[str, ...]:
    if command.kind != "parse":
        return ()  # only the parser's options are wanted
    return tuple("1" if PLACEHOLDER.search(w) else w for w in command.argv)


def run_bench_parsers(items: list[tuple[str, tuple[str, ...]]]) -> list[dict]:
    """Each ``(script, argv)`` parsed by the script's own parser: its visible options and
    its complaint (None: parsed)."""
    done = subprocess.run(
        [sys.executable, "-c", RUNNER], input=json.dumps(items), cwd=ROOT,
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    last = done.stdout.strip().splitlines()[-1:] or [""]
    assert done.returncode == 0 and last[0].startswith("RESULTS"), done.stderr[-3000:]
    return json.loads(last[0].removeprefix("RESULTS"))


@functools.cache
def bench_results() -> dict[tuple[str, tuple[str, ...]], dict]:
    """The parse of every benchmark command of the docs, in one subprocess."""
    items = sorted({(c.program, _bench_argv(c)) for c in ALL if c.program != "aes-swarm"})
    return dict(zip(items, run_bench_parsers(items), strict=True))


def check_bench(command: Command, result: dict | None = None) -> str | None:
    """Why the benchmark ``command`` does not parse, or None."""
    if result is None:
        result = bench_results()[(command.program, _bench_argv(command))]
    if command.kind == "parse" or result["options"] is None:
        return result["error"]
    flags = (re.match(r"-[-\w]+", w.strip("[]{}")) for w in command.argv)
    unknown = [m.group() for m in flags if m and m.group() not in result["options"]]
    return f"unknown or deprecated flags {unknown}" if unknown else None


def check(command: Command) -> str | None:
    """Why ``command`` does not parse, or None."""
    if command.program != "aes-swarm":
        return check_bench(command)
    parser = build_parser()
    commands = _subparsers(parser)
    argv = list(command.argv)
    if not argv or argv[0] in ("-h", "--help"):
        return None
    if PLACEHOLDER.search(argv[0]):
        return None  # "aes-swarm COMMAND -h"
    if argv[0] not in commands:
        return f"unknown subcommand {argv[0]!r}"
    sub = commands[argv[0]]
    if command.kind == "listing":
        return None
    if command.kind == "flags":
        known = _visible_options(sub)
        flags = (re.match(r"-[-\w]+", w.strip("[]{}")) for w in argv[1:])
        unknown = [m.group() for m in flags if m and m.group() not in known]
        return f"unknown or deprecated flags {unknown}" if unknown else None
    holes = [i for i, w in enumerate(argv) if i > 0 and PLACEHOLDER.search(w)]
    first = None
    for values in itertools.product(*(_candidates(sub, argv, i) for i in holes)):
        trial = list(argv)
        for i, value in zip(holes, values, strict=True):
            trial[i] = value
        complaint = _parse(parser, trial)
        if complaint is None:
            return None
        first = first or complaint
    return first


@pytest.mark.parametrize("command", ALL, ids=[c.where for c in ALL])
def test_documented_command_parses(command: Command) -> None:
    complaint = check(command)
    assert complaint is None, f"{command.where}: `{command.text}`\n{complaint}"


def test_the_docs_show_commands() -> None:
    """The extraction finds the README's demo and a command of every kind."""
    assert any(c.path.name == "README.md" and "launch" in c.argv[:1] for c in ALL)
    assert {c.kind for c in ALL} >= {"parse", "flags"}


def test_a_bad_flag_is_caught(tmp_path: Path) -> None:
    doc = tmp_path / "x.md"
    doc.write_text(
        "```bash\naes-swarm simulate --no-such-flag 3 \\\n  --out out/x   # a comment\n"
        "aes-swarm launch --robots <N> --out DIR\n"
        "aes-swarm steer [--omega W | --wrong X]\n```\n"
    )
    bad, good, synopsis = commands_of(doc)
    assert (bad.line, bad.argv) == (2, ("simulate", "--no-such-flag", "3", "--out", "out/x"))
    assert "--no-such-flag" in (check(bad) or "")
    assert check(good) is None
    assert synopsis.kind == "flags" and "--wrong" in (check(synopsis) or "")


def test_a_bad_benchmark_flag_is_caught(tmp_path: Path) -> None:
    doc = tmp_path / "x.md"
    doc.write_text(
        "Run `python bench/bench_sim.py --no-such-flag`\nor\n"
        "```\n.venv/bin/python bench/bench_sim.py --help\n```\n"
    )
    bad, good = commands_of(doc)
    assert (bad.line, bad.program, bad.argv) == (1, "bench/bench_sim.py", ("--no-such-flag",))
    results = run_bench_parsers([(c.program, _bench_argv(c)) for c in (bad, good)])
    assert "--no-such-flag" in (check_bench(bad, results[0]) or "")
    assert check_bench(good, results[1]) is None


def ros_parameters() -> dict[str, set[str]]:
    """Each node script's and node's parameters, from the generated docs/interface.md
    (itself checked against the nodes by test_reference_docs.py)."""
    text = (ROOT / "docs" / "interface.md").read_text()
    out: dict[str, set[str]] = {}
    for script, label, body in re.findall(
        r"^### (\S+)\n\nNode `([^`]+)`\.\n(.*?)(?=^##|\Z)", text, re.M | re.S
    ):
        names = set(re.findall(r"^\| `(\w+)` \|", body, re.M)) | {"use_sim_time"}
        out[script] = out[label.replace("<i>", "0")] = names
    return out


def parameter_uses(path: Path) -> list[tuple[int, str, str]]:
    """``(line, node or script, parameter)`` of every ``aes-… --ros-args -p name:=value``
    and ``ros2 param set /node name …`` in the code of ``path``."""
    text = path.read_text()
    found = []
    for number, line in [*fenced_lines(text), *inline_spans(text)]:
        words = _words(line)
        for i, word in enumerate(words):
            if word.startswith("aes-") and word != "aes-swarm" and "--ros-args" in words[i:]:
                found += [
                    (number, word, w.split(":=")[0])
                    for p, w in itertools.pairwise(words[i:])
                    if p == "-p" and ":=" in w
                ]
            if words[i : i + 3] == ["ros2", "param", "set"] and len(words) > i + 4:
                if not words[i + 3].startswith("/"):
                    continue
                node = re.sub(r"/mona_\d+/", "/mona_0/", words[i + 3])
                found.append((number, node, words[i + 4]))
    return found


USES = [
    (path, *use) for path in DOCS if path.name != "interface.md" for use in parameter_uses(path)
]


@pytest.mark.parametrize(
    ("path", "line", "node", "name"), USES, ids=[f"{p.name}:{n}:{x}" for p, n, _, x in USES]
)
def test_documented_ros_parameter_exists(path: Path, line: int, node: str, name: str) -> None:
    known = ros_parameters()
    where = f"{path.relative_to(ROOT)}:{line}"
    assert node in known, f"{where}: no node or node script {node!r} in docs/interface.md"
    assert name in known[node], f"{where}: {node} has no parameter {name!r}"


def test_a_wrong_ros_parameter_is_caught(tmp_path: Path) -> None:
    doc = tmp_path / "x.md"
    doc.write_text(
        "```\naes-supervisor --ros-args -p omega:=0.5 -p rotation_rate:=0.5\n```\n"
        "and `ros2 param set /mona_7/aes_robot direction 1.0`\n"
    )
    known = ros_parameters()
    uses = parameter_uses(doc)
    assert uses == [
        (2, "aes-supervisor", "omega"),
        (2, "aes-supervisor", "rotation_rate"),
        (4, "/mona_0/aes_robot", "direction"),
    ]
    assert [name in known[node] for _, node, name in uses] == [False, True, False]
