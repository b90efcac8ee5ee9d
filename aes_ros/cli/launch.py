"""``aes-swarm launch``: the whole ROS system (bridge, supervisor, robot nodes).

Examples::

    aes-swarm launch --setup combined --robots 100 --duration 30 --out out/ros \
        --record out/ros/run.mcap
    aes-swarm launch --setup linear --robots 16 --lockstep --real-time-factor 0 --out out/lin
    aes-swarm launch --setup combined --robots 100 --duration 0 --out out/long \
        --record out/long/run.mcap --bag-split 10min --bag-keep 12
    aes-swarm launch --robots 1000 --discovery server --out out/big   # . out/big/ros_env.sh
    aes-swarm launch --robots 25 --perception sigma=0.003,delay=0.05,rate=20,miss=0.01

``launch`` starts ``aes-sim-bridge``, ``aes-supervisor`` and the robot hosts
as separate processes (see :mod:`aes_ros.ros.launch`), waits until every
robot moves, runs ``--duration`` seconds of sim time (0: until Ctrl-C), stops
every process and writes the same outputs as ``aes-swarm simulate``. A launch whose
``--out`` holds an earlier run, or whose ``--record`` names an earlier recording, is
refused before anything starts (exit code 2) unless ``--overwrite``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from aes_ros import scenario
from aes_ros.cli.deprecated import add_deprecated
from aes_ros.cli.options import (
    add_scenario_options,
    add_seed_option,
    duration_type,
    load_scenario,
    number_type,
    scenario_label,
)
from aes_ros.previous_run import add_overwrite_option
from aes_ros.ros.bag import SPLIT_FORMS, bag_segments, parse_split
from aes_ros.ros.discovery import DISCOVERY_MODES, DISCOVERY_SERVER_FROM, parse_address
from aes_ros.ros.interface import LAYOUTS, MODES, NEIGHBOR_SOURCES
from aes_ros.ros.launch.config import FIRMWARES, ON_FAILURE, TRACKING, WORLDS


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_options(p)
    p.add_argument(
        "--layout", choices=LAYOUTS, default="auto",
        help="robot processes: auto (default: one while it carries the load, else one "
        "per core), one for all, one per core, or one per robot",
    )  # fmt: skip
    p.add_argument(
        "--neighbor-source", choices=NEIGHBOR_SOURCES, default="poses",
        help="neighbour positions from /swarm/poses (default) or the neighbours' odom",
    )  # fmt: skip
    p.add_argument(
        "--mode", choices=MODES, default="kinematic",
        help="kinematic: bodies follow cmd_vel exactly; dynamic: wheel motors and collisions",
    )  # fmt: skip
    p.add_argument(
        "--duration", type=duration_type(open_ended=True), default=None, metavar="S",
        help="sim time [s] to run after every robot moves (default: the scenario's "
        "duration; 0: until Ctrl-C)",
    )  # fmt: skip
    add_seed_option(p, "a launch is run 0, seeded S")
    p.add_argument(
        "--record", type=Path, default=None, metavar="FILE.mcap",
        help="record /swarm/*, /clock and every cmd_vel to a ROS 2 MCAP bag; where an "
        "earlier recording's files are (FILE, its segments FILE_1.mcap …) it is refused "
        "unless --overwrite",
    )  # fmt: skip
    p.add_argument(
        "--record-images", type=number_type(float, 0.0, 240.0), default=0.0, metavar="RATE",
        help="with --record and --tracking camera: also the camera's frames, at most RATE a "
        "second (default 0: none; a 1280x960 frame is 1.2 MB)",
    )  # fmt: skip
    p.add_argument(
        "--bag-split", type=_bag_split, default=None, metavar="SIZE|DURATION",
        help="with --record: once a bag segment reaches this size on disk or spans this "
        "wall time, close it (complete, with its own counts and losses) and go on in the "
        "next, run_1.mcap, run_2.mcap, ... (the numbering a restarted recorder continues); "
        "each starts with the last message of every latched topic. A size (500MiB, 1GiB; "
        "at least 64KiB) or a duration (30s, 10min, 2h; at least 1s); default: one segment",
    )  # fmt: skip
    p.add_argument(
        "--bag-keep", type=number_type(int, 1), default=None, metavar="K",
        help="with --bag-split: keep only the newest K segments (K >= 1), deleting older "
        "ones as new ones start (default: all)",
    )  # fmt: skip
    p.add_argument(
        "--out", type=Path, default=None, metavar="DIR",
        help="the directory this command writes (plots, metrics, logs); one that holds an "
        "earlier run's outputs is refused unless --overwrite",
    )  # fmt: skip
    add_overwrite_option(p, "outputs in --out and recording at --record")
    p.add_argument("--gui", action="store_true", help="show the pybullet GUI")
    p.add_argument(
        "--lockstep", action="store_true",
        help="each control step waits for every robot's command (deterministic)",
    )  # fmt: skip
    p.add_argument(
        "--real-time-factor", type=number_type(float, 0), default=1.0,
        metavar="X", help="sim speed relative to wall time (0: as fast as possible; default 1)",
    )  # fmt: skip
    p.add_argument(
        "--on-failure", choices=ON_FAILURE, default="respawn",
        help="a process that dies during the run: restart it (default; the bridge from the "
        "last world state, the recorder into a new bag segment), continue without it, or "
        "stop the run; every fault goes to OUT/events.csv",
    )  # fmt: skip
    p.add_argument(
        "--dashboard", nargs="?", const=8080, default=None, type=number_type(int, 0, 65535),
        metavar="PORT",
        help="also start the browser dashboard on http://127.0.0.1:PORT/ (default 8080; "
        "0: any free port) and print its URL",
    )  # fmt: skip
    p.add_argument(
        "--discovery", choices=DISCOVERY_MODES, default="auto",
        help="how the processes find each other: Fast DDS's simple discovery, or a "
        "discovery server (started as one more process of the launch unless "
        "--discovery-server is given; ros2 commands then need the environment it prints, "
        "also in OUT/ros_env.sh); auto (default): a server with --discovery-server or "
        f"--discovery-port, or from {DISCOVERY_SERVER_FROM} robots "
        "(measured: docs/performance.md)",
    )  # fmt: skip
    p.add_argument(
        "--discovery-server", type=_address, default=None, metavar="HOST:PORT",
        help="use this running discovery server (id 0, e.g. on another host) instead of "
        "starting one",
    )  # fmt: skip
    p.add_argument(
        "--discovery-port", type=number_type(int, 1, 65535), default=None, metavar="PORT",
        help="the UDP port of the discovery server the launch starts (default: a free one)",
    )  # fmt: skip
    p.add_argument(
        "--tracking", choices=TRACKING, default="none",
        help="camera: the robots take their neighbours' positions from a simulated overhead "
        "camera and the ArUco tracker; the bridge's exact poses go to /sim/ground_truth/poses "
        "(the outputs' source). The arena (--set arena=[x0,x1,y0,y1], else the formation "
        "with 0.5 m around it) is what the camera sees and what the supervisor keeps the "
        "swarm in",
    )  # fmt: skip
    p.add_argument(
        "--world", choices=WORLDS, default="pybullet",
        help="pybullet (default): the simulated robots; none: a real arena, no bridge, "
        "every node on wall-clock time, the robots' drivers take /mona_<i>/cmd_vel (needs "
        "--tracking camera, --camera-source, --calibration; docs/real_robots.md)",
    )  # fmt: skip
    p.add_argument(
        "--firmware", choices=FIRMWARES, default="none",
        help="none (default): the simulated wheels follow /mona_<i>/cmd_vel; sil: through "
        "the real firmware, one simulated MCU (mona-sil) per robot driven by aes-mona-driver "
        "(needs make -C firmware; not with --world none or --lockstep; docs/firmware.md)",
    )  # fmt: skip
    p.add_argument(
        "--camera-source", default=None, metavar="DEVICE",
        help="with --world none: the overhead camera (/dev/video0, its number, or a video file)",
    )  # fmt: skip
    p.add_argument(
        "--calibration", type=Path, default=None, metavar="FILE",
        help="with --world none: the camera's calibration (aes-swarm calibrate)",
    )  # fmt: skip
    p.add_argument(
        "--perception", type=_perception, default={}, metavar="sigma=M,delay=S,rate=HZ,miss=P",
        help="the robots see /swarm/poses through the offline simulator's perception model "
        "(aes_ros.perception): position noise sigma [m], delay [s], camera rate [Hz; 0: every "
        "step], miss probability per robot and frame; any of the four, e.g. "
        "sigma=0.003,delay=0.05,rate=20,miss=0.01 (the same as --set perception_sigma=0.003 "
        "…). The bridge's exact poses go to /sim/ground_truth/poses (the outputs' source)",
    )  # fmt: skip
    p.add_argument(
        "--camera-size", type=_pixels, default=(1280, 960), metavar="WxH",
        help="the simulated camera's image size (default 1280x960)",
    )  # fmt: skip
    add_deprecated(p, "--camera", "--camera-size")
    p.add_argument(
        "--camera-rate", type=number_type(float, 0.1, 240.0), default=20.0, metavar="HZ",
        help="the simulated camera's frames per second of sim time (default 20)",
    )  # fmt: skip


def _bag_split(text: str) -> str:
    """``--bag-split``: a size or a duration (:func:`aes_ros.ros.bag.parse_split`)."""
    try:
        parse_split(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: need {SPLIT_FORMS}") from None
    return text.strip()


def _address(text: str) -> str:
    """``HOST:PORT`` of a discovery server (:func:`aes_ros.ros.discovery.parse_address`)."""
    try:
        host, port = parse_address(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return f"{host}:{port}"


#: ``--perception`` keys and the parameters they set.
PERCEPTION_KEYS = {k: f"perception_{k}" for k in ("sigma", "delay", "rate", "miss")}


def _perception(text: str) -> dict[str, float]:
    """``--perception sigma=…,delay=…,rate=…,miss=…``: the ``perception_*`` overrides,
    each validated against its parameter's range."""
    from aes_ros.params import ParameterError, validate_params

    values = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep or key.strip() not in PERCEPTION_KEYS:
            raise argparse.ArgumentTypeError(
                f"{item!r}: expected KEY=VALUE with KEY one of {', '.join(PERCEPTION_KEYS)}"
            )
        values[PERCEPTION_KEYS[key.strip()]] = value.strip()
    try:
        return validate_params(values, "--perception")
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _pixels(text: str) -> tuple[int, int]:
    """``WxH`` in pixels, each 16 … 8192."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected WxH, e.g. 1280x960") from None
    if not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise argparse.ArgumentTypeError(f"{text!r}: each side 16 … 8192 px")
    return width, height


def run(args: argparse.Namespace) -> int:
    from aes_ros.ros.launch import LaunchConfig, LaunchError, launch, preflight

    sc = load_scenario(args)
    if args.perception:
        sc = sc.with_overrides(args.perception, "--perception")
    overrides = scenario.parse_assignments(args.set)
    try:
        config = LaunchConfig(
            scenario=sc,
            label=f"{scenario_label(args)} (ROS)",
            layout=args.layout,
            neighbor_source=args.neighbor_source,
            mode=args.mode,
            duration=None,  # load_scenario already applied --duration to the scenario
            seed=args.seed,
            record=args.record,
            out_dir=args.out,
            gui=args.gui,
            lockstep=args.lockstep,
            real_time_factor=args.real_time_factor,
            clip=bool(sc.clip) if "clip" in overrides else None,
            on_failure=args.on_failure,
            dashboard=args.dashboard,
            tracking=args.tracking,
            camera_size=args.camera_size,
            camera_rate=args.camera_rate,
            world=args.world,
            firmware=args.firmware,
            record_images=args.record_images,
            bag_split=args.bag_split,
            bag_keep=args.bag_keep,
            camera_source=args.camera_source,
            calibration=args.calibration,
            discovery=args.discovery,
            discovery_server=args.discovery_server,
            discovery_port=args.discovery_port,
            overwrite=args.overwrite,
        )
    except ValueError as exc:  # an option that does not fit the others, named
        print(f"aes-swarm launch: error: {exc}", file=sys.stderr)
        return 2
    preflight.earlier_run(config)  # an EarlierRunError: exit code 2, before anything starts
    if args.dashboard is not None:  # its token from the environment, if given: usable?
        import os

        from aes_ros.ros.dashboard_token import TokenError, given_token

        try:
            given_token(os.environ)
        except TokenError as exc:
            print(f"aes-swarm launch: error: {exc}", file=sys.stderr)
            return 2
    try:
        result = launch(config, say=lambda line: print(line, flush=True))
    except LaunchError as exc:
        print(f"aes-swarm launch: error: {exc}", file=sys.stderr)
        return 1
    if result.summary:
        print(f"{result.summary}  [{result.wall_time:.1f} s wall, outputs in {args.out}]")
    else:
        span = result.t_last - result.t_go if result.samples else 0.0
        print(f"launch: ran {span:.1f} s of sim time in {result.wall_time:.1f} s wall")
    if args.record is not None:  # its segments, when it was split or restarted
        segments = bag_segments(args.record) or [args.record]
        print(f"bag: {', '.join(map(str, segments))}")
    if result.failure is not None:
        print(f"aes-swarm launch: error: {result.failure}", file=sys.stderr)
        return 1
    return 0
