"""Write docs/cli.md, docs/interface.md and tests/README.md from the code.

docs/cli.md comes from the ``aes-swarm`` parser; docs/interface.md from the tables
of ``aes_ros/ros/interface.py`` and from every node, built once in this process with
discovery off (it reaches no other process): the parameters it declares, the topics
(with QoS) and services it creates. tests/README.md maps each module to the test
files that import it, start its console script or run its subcommand. Run it after
changing any of them (tests/unit/test_reference_docs.py fails until then)::

    .venv/bin/python scripts/make_reference.py          # rewrite the stale files
    .venv/bin/python scripts/make_reference.py --check  # exit 1 if one is stale
"""

from __future__ import annotations

import argparse
import ast
import importlib
import os
import re
import subprocess
import sys
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aes_ros.arena_layout import corner_layout, save_layout  # noqa: E402
from aes_ros.cli.reference import (  # noqa: E402
    GENERATED,
    NODES,
    cell,
    cli_markdown,
    console_scripts,
    endpoints_markdown,
)
from aes_ros.ros import interface  # noqa: E402
from aes_ros.ros.parameter_table import NODE_PARAMETERS, node_label  # noqa: E402

CLI_DOC = ROOT / "docs" / "cli.md"
INTERFACE_DOC = ROOT / "docs" / "interface.md"
TESTS_DOC = ROOT / "tests" / "README.md"
#: Declared by rclpy for every node.
RCLPY_OWN = {"use_sim_time", "start_type_description_service"}
#: Topics rclpy creates for every node.
RCLPY_TOPICS = {"/rosout", "/parameter_events"}
#: The services rclpy gives every node, ``/<node>/<name>``.
PARAMETER_SERVICES = {"describe_parameters", "get_parameter_types", "get_parameters",
                      "get_type_description", "list_parameters", "set_parameters",
                      "set_parameters_atomically"}  # fmt: skip


@dataclass
class BuiltNode:
    """What one node declared and created: parameters ``(name, type, default cell,
    descriptor)`` in order, and its topics and services by kind."""

    name: str
    parameters: list[tuple[str, str, str, Any]]
    endpoints: dict[str, dict[str, str]]


def _setup(script: str, tmp: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Parameter overrides and constructor arguments that let the node of ``script``
    start here. The recorded defaults stay the code's."""
    if script == "aes-robot-node":
        return {}, {"namespace": "/mona_0"}  # as the launch starts it
    if script == "aes-robot-host":
        return {"num_robots": 2}, {}  # two robots keep it quick
    if script == "aes-tracker":  # it needs a calibration or a layout
        layout = save_layout(corner_layout((-1.0, 1.0, -0.75, 0.75)), tmp / "arena.yaml")
        return {"layout": str(layout)}, {}
    if script == "aes-mona-driver":
        return {}, {"links": []}
    return {}, {}


def _qos(profile: Any) -> str:
    """A QoS profile in a few words: reliability, durability if transient local, history."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

    words = ["reliable" if profile.reliability == ReliabilityPolicy.RELIABLE else "best effort"]
    if profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
        words.append("transient local")
    keep_all = profile.history == HistoryPolicy.KEEP_ALL
    words.append("keep all" if keep_all else f"depth {profile.depth}")
    return ", ".join(words)


def _endpoints(node: Any) -> dict[str, dict[str, str]]:
    """The node's topics (with their QoS) and services without rclpy's own, by kind;
    ``/mona_<i>`` for any robot."""

    def listed(items: Any, attr: str, topics: bool, own: bool = False) -> dict[str, str]:
        out: dict[str, set[str]] = {}
        for x in items:
            name = re.sub(r"^/?mona_\d+/", "/mona_<i>/", getattr(x, attr))
            if name in RCLPY_TOPICS or (own and name.rsplit("/", 1)[-1] in PARAMETER_SERVICES):
                continue
            out.setdefault(name, set()).add(_qos(x.qos_profile) if topics else "")
        return {name: "; ".join(sorted(out[name])) for name in sorted(out)}

    return {
        "publishes": listed(node.publishers, "topic_name", True),
        "subscribes to": listed(node.subscriptions, "topic_name", True),
        "serves": listed(node.services, "srv_name", False, own=True),
        "calls": {n: "" for n in listed(node.clients, "srv_name", False)},
    }


def build_node(script: str, target: str, context: Any, tmp: Path) -> BuiltNode:
    """Build the node class ``target`` (``module:Class``) and record what it declares
    (defaults as the code gives them, with the ``combined`` scenario; types as the
    node holds them) and creates."""
    from rclpy.parameter import Parameter

    module, name = target.split(":")
    cls = getattr(importlib.import_module(module), name)
    seen: list[tuple[str, Any, Any]] = []
    made: list[Any] = []

    class Recording(cls):  # type: ignore[misc, valid-type]
        def declare_parameters(self, namespace: str, parameters: Any, ignore_override=False):
            made[:] = [self]
            for p in parameters:
                seen.append((p[0], p[1] if len(p) > 1 else None, p[2] if len(p) > 2 else None))
            return super().declare_parameters(namespace, parameters, ignore_override)

    values, kwargs = _setup(script, tmp)
    overrides = [Parameter(k, value=v) for k, v in values.items()]
    Recording(context=context, parameter_overrides=overrides, **kwargs)
    node = made[0]
    out = []
    for pname, default, descriptor in seen:
        if isinstance(default, Parameter.Type):  # declared with a type, no value
            kind = default.name.lower().replace("_array", "[]")
        else:
            kind = node.get_parameter(pname).type_.name.lower().replace("_array", "[]")
        shown = "" if isinstance(default, Parameter.Type) or default == "" else f"`{cell(default)}`"
        out.append((pname, kind, shown, descriptor))
    built = BuiltNode(node.get_name(), out, _endpoints(node))
    node.destroy_node()
    return built


def _check_listed(script: str, built: BuiltNode) -> None:
    """Every topic and service the node creates is in interface.py's tables."""
    listed = {e.name for e in (*interface.TOPICS, *interface.SERVICES)}
    listed |= {re.sub(r"<k>$", "", n) for n in listed}
    missing = [
        n for names in built.endpoints.values() for n in names
        if n not in listed and re.sub(r"\d+$", "", n) not in listed
        and n.rsplit("/", 1)[-1] not in PARAMETER_SERVICES
    ]  # fmt: skip
    if missing:
        raise SystemExit(
            f"{script} creates {', '.join(missing)}: add them to TOPICS or SERVICES "
            "in aes_ros/ros/interface.py"
        )


def parameters_markdown() -> list[str]:
    """One section per node: its topics and services, and a table of its parameters."""
    import rclpy
    from rclpy.context import Context

    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"
    os.environ.pop("ROS_DISCOVERY_SERVER", None)
    os.environ.pop("ROS_STATIC_PEERS", None)
    context = Context()
    rclpy.init(args=["--ros-args", "--log-level", "fatal"], context=context)
    lines = [
        "## Nodes",
        "",
        "What each node creates when it starts (`/mona_<i>` for every robot it knows), "
        "and its parameters. Parameters are set at start with `--ros-args -p name:=value`, "
        "at runtime with a parameter service unless read-only; an invalid value is refused "
        "with a reason and the old one stays. Defaults are those of the `combined` "
        "scenario: the model parameters (`alpha`, `beta`, `k`, …) default to the "
        "scenario's values. The column `params` names the `aes-swarm params` / `--set` "
        "entry a parameter stands for (`aes-swarm params --ros` prints the same mapping). "
        "Every node also has rclpy's `use_sim_time`.",
        "",
    ]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for script, target in NODES.items():
                if script in console_scripts():
                    lines += node_section(script, build_node(script, target, context, Path(tmp)))
    finally:
        rclpy.try_shutdown(context=context)
    return lines


def node_section(script: str, built: BuiltNode) -> list[str]:
    """The markdown of one node."""
    _check_listed(script, built)
    table = NODE_PARAMETERS.get(built.name)
    params_names = dict(table.rows()) if table is not None else {}
    lines = [f"### {script}", "", f"Node `{node_label(built.name)}`.", ""]
    for verb, names in built.endpoints.items():
        shown = [f"`{n}` ({qos})" if qos else f"`{n}`" for n, qos in names.items()]
        if shown:
            lines.append(f"- {verb} {', '.join(shown)}")
    lines += ["", "| parameter | type | default | `params` | what |", "|---|---|---|---|---|"]
    for name, kind, shown, descriptor in built.parameters:
        if name in RCLPY_OWN:
            continue
        text = descriptor.description if descriptor is not None else ""
        ro = " (read-only)" if descriptor is not None and descriptor.read_only else ""
        same = params_names.get(name)
        same = f"`{same}`" if same else ""
        lines.append(f"| `{name}` | {kind} | {shown} | {same} | {cell(text)}{ro} |")
    return [*lines, ""]


def interface_markdown() -> str:
    """The text of docs/interface.md."""
    lines = [
        "# ROS interface",
        "",
        GENERATED,
        "",
        "The topics, services and node parameters of a running swarm. `/mona_<i>` is "
        "robot i's namespace. Message types are the standard ROS 2 ones.",
        "",
        *endpoints_markdown(),
        *parameters_markdown(),
    ]
    return "\n".join(lines).rstrip() + "\n"


def python_files(folder: str, pattern: str) -> list[Path]:
    """The files of ``folder`` named like ``pattern`` that git tracks (all of them outside
    a git clone), so that files not committed yet do not enter the tables."""
    found = sorted((ROOT / folder).rglob(pattern))
    try:
        listed = subprocess.run(
            ["git", "ls-files", "-z", "--", folder], cwd=ROOT, capture_output=True,
            text=True, check=True,
        ).stdout.split("\0")  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return found
    tracked = {ROOT / name for name in listed if name}
    return [path for path in found if path in tracked]


def project_modules() -> list[str]:
    """Every module of the packages that pyproject.toml installs, dotted."""
    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    tops = sorted(p.rstrip("*") for p in find["packages"]["find"]["include"])
    out = []
    for top in tops:
        for path in python_files(top, "*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def tested_modules(path: Path, modules: set[str], scripts: dict[str, str]) -> set[str]:
    """The project modules the test file ``path`` imports, starts (console script,
    ``-m``) or runs as an ``aes-swarm`` subcommand."""
    tree = ast.parse(path.read_text())
    found: set[str] = set()
    strings: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names = {f"{node.module}.{a.name}" for a in node.names}
            found.update(names & modules or {node.module})
            if node.module == "aes_ros.cli" and "aes_ros.cli.main" in names:
                strings.add("aes-swarm")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            strings.add(node.value)
    for text in strings:
        if text in scripts:
            found.add(scripts[text].split(":")[0])
        found.add(text)  # "-m", "aes_ros.x" and subcommand names
    if "aes-swarm" in strings:
        found.update(f"aes_ros.cli.{name}" for name in strings)
    return found & modules


def tests_markdown() -> str:
    """The text of tests/README.md."""
    modules = project_modules()
    scripts = console_scripts()
    tests: dict[str, list[str]] = {m: [] for m in modules}
    for path in python_files("tests", "test_*.py"):
        for module in tested_modules(path, set(modules), scripts):
            tests[module].append(f"[{path.name}]({path.relative_to(ROOT / 'tests')})")
    lines = [
        "# Tests",
        "",
        GENERATED,
        "",
        "`tests/unit` runs no ROS process (seconds); `tests/system` starts real nodes over "
        "Fast DDS, each test in a ROS domain of its own (marker `ros`); `tests/helpers` is "
        "what both share. Run the tests of one module with "
        "`.venv/bin/python -m pytest -q tests/unit/test_x.py`. Below: each module and the "
        "test files that import it, start its console script or run its `aes-swarm` "
        "subcommand (a module tested only through another is listed without).",
        "",
        "| module | tests |",
        "|---|---|",
    ]
    for module in modules:
        lines.append(f"| `{module}` | {', '.join(tests[module])} |")
    return "\n".join([*lines, ""])


def main(argv: list[str] | None = None) -> int:
    """Write the references, or with ``--check`` name the stale ones (exit 1)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--check", action="store_true", help="only compare; exit 1 if stale")
    args = parser.parse_args(argv)
    stale = []
    made = (
        (CLI_DOC, cli_markdown),
        (INTERFACE_DOC, interface_markdown),
        (TESTS_DOC, tests_markdown),
    )
    for path, make in made:
        text = make()
        if path.exists() and path.read_text() == text:
            continue
        stale.append(str(path.relative_to(ROOT)))
        if not args.check:
            path.write_text(text)
            print(f"wrote {path.relative_to(ROOT)}")
    if args.check and stale:
        print(f"stale: {', '.join(stale)}; run: python scripts/make_reference.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
