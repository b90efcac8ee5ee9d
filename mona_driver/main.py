"""``aes-mona-driver``'s command line: the links are parsed and opened before ROS starts.

A link string that cannot be parsed or a device that cannot be opened ends the
process with exit code 2 and the reason, before rclpy is even imported; then
:class:`mona_driver.node.MonaDriverNode` drives the robots until SIGINT or SIGTERM.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from mona_driver.links import FORMS, LinkError, LinkSpec, load_links_file, parse_links
from mona_driver.robot import RobotLink
from mona_driver.transport import SerialPort, UdpHub, UdpPort

PROG = "aes-mona-driver"


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """The driver's own options (those before ``--ros-args``)."""
    epilog = "ROS parameters: aes-mona-driver ... --ros-args -p NAME:=VALUE."
    if "-h" in argv or "--help" in argv:  # only then: the node's module pulls in rclpy
        import inspect

        from mona_driver.node import MonaDriverNode

        epilog += "\n\n" + (inspect.getdoc(MonaDriverNode) or "")
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Drive real Monas over the Mona link v1 (docs/mona_protocol.md).",
        epilog=epilog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add = parser.add_argument
    add("--link", action="append", default=[], help=f"one robot's link: {FORMS} (repeatable)")
    add("--links", metavar="FILE", help="a YAML list of link strings")
    add("--udp-port", type=int, default=0, metavar="PORT",
        help="the driver's UDP port for robots on Wi-Fi (0: any free port)")  # fmt: skip
    args = parser.parse_args(argv)
    if not 0 <= args.udp_port <= 65535:
        parser.error(f"--udp-port {args.udp_port}: must be in [0, 65535]")
    try:
        texts = [*(load_links_file(args.links) if args.links else []), *args.link]
        args.specs = parse_links(texts)
    except LinkError as exc:
        parser.error(str(exc))
    return args


def open_links(specs: list[LinkSpec], udp_port: int) -> tuple[list[RobotLink], UdpHub | None]:
    """Every link opened; :class:`LinkError` naming the first that cannot be."""
    hub = None
    links: list[RobotLink] = []
    try:
        if any(spec.kind == "udp" for spec in specs):
            try:
                hub = UdpHub(udp_port)
            except OSError as exc:
                raise LinkError(f"--udp-port {udp_port}: cannot bind: {exc.strerror}") from None
        for spec in specs:
            if spec.kind == "serial":
                link = RobotLink(spec, SerialPort(spec.device, spec.baud))
                reason = link.open(0.0)
                if reason is not None:
                    raise LinkError(f"link {spec}: {reason}")
            else:
                link = RobotLink(spec, UdpPort(hub, spec.address))  # type: ignore[arg-type]
            links.append(link)
    except LinkError:
        for link in links:
            link.transport.close()
        if hub is not None:
            hub.close()
        raise
    return links, hub


def main(args: list[str] | None = None) -> int:
    """``aes-mona-driver``: exit 2 if a link cannot be parsed or opened."""
    argv = list(sys.argv if args is None else args)
    own = argv[1 : argv.index("--ros-args")] if "--ros-args" in argv else argv[1:]
    options = parse_args(own)
    try:
        links, hub = open_links(options.specs, options.udp_port)
    except LinkError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    ros_args = argv[:1] + argv[len(own) + 1 :]
    from aes_ros.ros import interface as names
    from aes_ros.ros.spin import run_node_process
    from mona_driver.node import MonaDriverNode

    try:
        return run_node_process(
            names.MONA_DRIVER_NODE, ros_args, lambda: MonaDriverNode(links, hub)
        )
    finally:
        for link in links:
            link.transport.close()
        if hub is not None:
            hub.close()


if __name__ == "__main__":
    sys.exit(main())
