"""Benchmark of the Mona firmware on simulated MCUs: real time per core, command latency.

For each count K of simulated MCUs (``firmware/build/mona-sil`` running the real
``mona.elf``, one process each) a host thread plays the driver: every 50 ms it writes
a WHEELS to every pseudo-terminal (to MCU 0 alternately two speeds, so each one changes
its PWM) and drains what the firmware sends. Over ``--duration`` seconds after a 1 s
warm-up it measures:

- ``rtf_min`` / ``rtf_mean``: simulated seconds per wall second of the MCUs over the
  window (from their ``stats`` lines; 1.0 is real time, below it the MCU lags the wall
  clock);
- ``cpu_pct``: CPU of one ``mona-sil`` [% of one core], the mean over the K;
  ``per_core = 100 / cpu_pct``: MCUs one core keeps in real time at that cost;
- ``wheels_p50_ms`` / ``wheels_p99_ms``: wall time from writing a WHEELS on MCU 0's
  pty to its ``motors`` line (the PWM compare value changed) read by this script; it
  holds the 12 bytes of the frame on the simulated 115200 baud line (about 1 ms of
  simulated time, which ``mona-sil`` may run up to a few ms ahead of the wall clock).

Then the latency of a robot's command (:mod:`firmware_latency`): from publishing
``/mona_0/cmd_vel`` in this process, through ``aes-mona-driver``, the pty and the
firmware, to the PWM change (``mona-sil``'s ``motors`` line) and to the
``/mona_0/wheel_cmd`` that ``firmware_loop`` publishes from it, p50 / p99 over
``--latency-duration`` seconds of commands at 20 Hz.

Then, for each ``--robots`` count, the full chain: ``aes-swarm launch --firmware sil``
(robot node → ``cmd_vel`` → ``aes-mona-driver`` → bytes → firmware → PWM → pybullet
wheels) beside the same seed without firmware (:mod:`firmware_chain`): the real-time
factor of the bridge's clock, ψ̄ and ψ̄_heading of both runs and their |Δ|, and the CPU
of each kind of process mid-run (all MCUs summed), which names the bound where a count
falls short of real time.

Usage::

    python bench/bench_firmware.py                     # 1, 2, 4, 8, 16 MCUs, 5 s each
    python bench/bench_firmware.py --mcus 1,32 --duration 10
    python bench/bench_firmware.py --quick             # 1 and 2 MCUs, 2 s each, no chain
    python bench/bench_firmware.py --mcus 1 --robots ""   # the latencies, no chain
    python bench/bench_firmware.py --mcus 1 --robots 8 --chain-duration 30

Writes ``bench_firmware.csv`` to ``--out`` (default ``out/bench_firmware``), prints a
table and, last, ``RESULT mcus=<largest K> rtf_min=… cpu_pct=… per_core=… wheels_p50_ms=…
wheels_p99_ms=… machine_ref_us=…`` where the latency is that of one MCU alone, ``RESULT
latency cmd_vel_pwm_p50_ms=… cmd_vel_pwm_p99_ms=… cmd_vel_wheel_cmd_p50_ms=…
cmd_vel_wheel_cmd_p99_ms=… samples=… machine_ref_us=…``, and one ``RESULT chain
robots=N rtf=… psi=… psi_nofw=… dpsi=… psi_heading=… psi_heading_nofw=… dpsi_heading=…
machine_ref_us=…`` per ``--robots`` count. Every figure is printed beside
``machine_ref_us``: µs of one agent-step of ``bench/bench_sim.py``'s per-agent Python
loop, measured in the same run (see bench/bench_ros.py).
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import termios
import threading
import time
import tty
from dataclasses import dataclass, field
from pathlib import Path

import firmware_chain  # sibling scripts, not a package
import firmware_latency
from process_stats import machine_reference_us

from aes_ros.mona.messages import Wheels
from aes_ros.ros.launch.firmware import BUILD

FIRMWARE = BUILD.parent
ELF = BUILD / "mona.elf"
SIL = BUILD / "mona-sil"
PERIOD_S = 0.05  # the driver's WHEELS period: a 20 Hz control loop
WARMUP_S = 1.0
CLK_TCK = os.sysconf("SC_CLK_TCK")


@dataclass
class Mcu:
    """One ``mona-sil`` process, its pty and what its stdout said."""

    proc: subprocess.Popen[str]
    fd: int
    stats: list[tuple[float, float, float]] = field(default_factory=list)  # (now, t, wall)
    motors: list[float] = field(default_factory=list)  # wall times of motors lines

    @classmethod
    def start(cls) -> Mcu:
        proc = subprocess.Popen(
            [str(SIL), "--stats", "0.5", str(ELF)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert proc.stdout is not None
        line = proc.stdout.readline().split()
        if line[:1] != ["pty:"]:
            raise RuntimeError(f"mona-sil did not start: {line}")
        fd = os.open(line[1], os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(fd, termios.TCSANOW)
        mcu = cls(proc, fd)
        threading.Thread(target=mcu._read, daemon=True).start()
        return mcu

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            now = time.monotonic()
            if line.startswith("motors "):
                self.motors.append(now)
            elif line.startswith("stats "):
                fields = dict(part.split("=") for part in line.split()[1:])
                self.stats.append((now, float(fields["t"]), float(fields["wall"])))

    def cpu_s(self) -> float:
        fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / CLK_TCK

    def stop(self) -> None:
        os.close(self.fd)
        self.proc.terminate()
        self.proc.wait(timeout=10)


def drive(mcus: list[Mcu], until: float, sends: list[float]) -> None:
    """Write WHEELS to every MCU each period until ``until``; drain their output.

    MCU 0 gets two speeds in turn, so every WHEELS changes its PWM; ``sends`` gets the
    wall time of each of those writes."""
    seq, tick = 0, time.monotonic()
    while tick < until:
        seq = (seq + 1) & 0xFFFF
        for i, mcu in enumerate(mcus):
            left = (40 if seq % 2 else 90) if i == 0 else 60
            frame = Wheels(left, 60, 500).encode(seq)
            if i == 0:
                sends.append(time.monotonic())
            os.write(mcu.fd, frame)
            try:
                while os.read(mcu.fd, 4096):
                    pass
            except BlockingIOError:
                pass
        tick += PERIOD_S
        time.sleep(max(0.0, tick - time.monotonic()))


def latencies_ms(sends: list[float], motors: list[float]) -> list[float]:
    """Each motors line against the last WHEELS written before it."""
    out, j = [], 0
    for t in motors:
        while j + 1 < len(sends) and sends[j + 1] <= t:
            j += 1
        if sends and sends[j] <= t and t - sends[j] < PERIOD_S:
            out.append((t - sends[j]) * 1e3)
    return out


def rtf(mcu: Mcu, start: float, end: float) -> float:
    """Simulated over wall seconds of ``mcu`` between its first and last stats line in
    [start, end] (one ratio over the window: the MCU may run a few ms ahead at a time)."""
    lines = [(t, wall) for now, t, wall in mcu.stats if start < now <= end]
    if len(lines) < 2:
        return float("nan")
    return (lines[-1][0] - lines[0][0]) / (lines[-1][1] - lines[0][1])


def measure(k: int, duration: float) -> dict[str, float]:
    """Run ``k`` MCUs for the warm-up and ``duration`` seconds; their figures."""
    mcus = [Mcu.start() for _ in range(k)]
    try:
        sends: list[float] = []
        start = time.monotonic()
        end = start + WARMUP_S + duration
        driver = threading.Thread(target=drive, args=(mcus, end, sends), daemon=True)
        driver.start()
        time.sleep(WARMUP_S)
        window = time.monotonic()
        cpu0 = [m.cpu_s() for m in mcus]
        driver.join()
        wall = time.monotonic() - window
        cpu = [(m.cpu_s() - c) / wall * 100.0 for m, c in zip(mcus, cpu0, strict=True)]
        time.sleep(0.6)  # the last stats line of the window
        rtfs = [rtf(m, window, window + wall + 0.6) for m in mcus]
        lat = latencies_ms([s for s in sends if s >= window], mcus[0].motors)
    finally:
        for m in mcus:
            m.stop()
    q = statistics.quantiles(lat, n=100) if len(lat) >= 2 else [float("nan")] * 99
    cpu_pct = statistics.fmean(cpu)
    return {
        "mcus": k,
        "rtf_min": min(rtfs),
        "rtf_mean": statistics.fmean(rtfs),
        "cpu_pct": cpu_pct,
        "per_core": 100.0 / cpu_pct if cpu_pct > 0 else float("inf"),
        "wheels_p50_ms": q[49],
        "wheels_p99_ms": q[98],
        "samples": len(lat),
    }


def counts(text: str, empty: bool = False) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = [0]
    if (not values and not empty) or any(not 1 <= v <= 256 for v in values):
        raise argparse.ArgumentTypeError(f"'{text}': comma-separated counts in 1..256")
    return values


def robot_counts(text: str) -> list[int]:
    return counts(text, empty=True)  # "": no full chain


def seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.5 <= value <= 3600:
        raise argparse.ArgumentTypeError(f"'{text}': seconds in 0.5..3600 (0 is not a length)")
    return value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mcus", type=counts, default=[1, 2, 4, 8, 16], help="MCU counts")
    parser.add_argument(
        "--duration", type=seconds, default=5.0, help="measured seconds per count [s]"
    )
    parser.add_argument(
        "--robots",
        type=robot_counts,
        default=[8, 16],
        help='robot counts of the full chain ("": none)',
    )
    parser.add_argument(
        "--latency-duration", type=seconds, default=10.0,
        help="seconds of cmd_vel for the cmd_vel → PWM latency [s]",
    )  # fmt: skip
    parser.add_argument(
        "--chain-duration", type=seconds, default=20.0, help="sim seconds of each launch [s]"
    )
    parser.add_argument("--quick", action="store_true", help="1 and 2 MCUs, 2 s each, no chain")
    parser.add_argument("--out", type=Path, default=Path("out/bench_firmware"))
    args = parser.parse_args(argv)
    if args.quick:
        args.mcus, args.duration, args.robots, args.latency_duration = [1, 2], 2.0, [], 2.0
    build = subprocess.run(["make", "-s", "-C", str(FIRMWARE)], capture_output=True, text=True)
    if build.returncode != 0:
        print(f"make -C firmware failed:\n{build.stdout}{build.stderr}", file=sys.stderr)
        return 1

    ref_before = machine_reference_us()
    rows = []
    print(f"{'MCUs':>5} {'rtf min':>8} {'rtf mean':>8} {'CPU %':>6} {'per core':>8} "
          f"{'WHEELS→PWM p50 ms':>17} {'p99 ms':>7}", flush=True)  # fmt: skip
    for k in args.mcus:
        row = measure(k, args.duration)
        rows.append(row)
        print(f"{k:>5} {row['rtf_min']:>8.4f} {row['rtf_mean']:>8.4f} {row['cpu_pct']:>6.2f} "
              f"{row['per_core']:>8.0f} {row['wheels_p50_ms']:>17.2f} "
              f"{row['wheels_p99_ms']:>7.2f}", flush=True)  # fmt: skip
    lat = firmware_latency.measure(args.latency_duration, firmware_chain.ros_environment())
    print(f"cmd_vel → PWM p50 {lat['pwm_p50_ms']:.2f} ms, p99 {lat['pwm_p99_ms']:.2f} ms "
          f"({lat['pwm_samples']} of {lat['sent']}); cmd_vel → wheel_cmd p50 "
          f"{lat['wheel_cmd_p50_ms']:.2f} ms, p99 {lat['wheel_cmd_p99_ms']:.2f} ms "
          f"({lat['wheel_cmd_samples']})", flush=True)  # fmt: skip
    chain = [chain_row(n, args.chain_duration) for n in args.robots]
    ref = 0.5 * (ref_before + machine_reference_us())

    args.out.mkdir(parents=True, exist_ok=True)
    with (args.out / "bench_firmware.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=[*rows[0], "machine_ref_us"])
        writer.writeheader()
        writer.writerows({**r, "machine_ref_us": round(ref, 3)} for r in rows)
    largest = max(rows, key=lambda r: r["mcus"])
    alone = min(rows, key=lambda r: r["mcus"])
    print(
        f"RESULT mcus={largest['mcus']} rtf_min={largest['rtf_min']:.4f} "
        f"cpu_pct={largest['cpu_pct']:.2f} per_core={largest['per_core']:.0f} "
        f"wheels_p50_ms={alone['wheels_p50_ms']:.2f} wheels_p99_ms={alone['wheels_p99_ms']:.2f} "
        f"machine_ref_us={ref:.2f}"
    )
    print(
        f"RESULT latency cmd_vel_pwm_p50_ms={lat['pwm_p50_ms']:.2f} "
        f"cmd_vel_pwm_p99_ms={lat['pwm_p99_ms']:.2f} "
        f"cmd_vel_wheel_cmd_p50_ms={lat['wheel_cmd_p50_ms']:.2f} "
        f"cmd_vel_wheel_cmd_p99_ms={lat['wheel_cmd_p99_ms']:.2f} "
        f"samples={lat['pwm_samples']} machine_ref_us={ref:.2f}"
    )
    for row in chain:
        print(
            f"RESULT chain robots={row['robots']} rtf={row['rtf']:.3f} psi={row['psi']:.3f} "
            f"psi_nofw={row['psi_nofw']:.3f} dpsi={row['dpsi']:.3f} "
            f"psi_heading={row['psi_heading']:.3f} "
            f"psi_heading_nofw={row['psi_heading_nofw']:.3f} "
            f"dpsi_heading={row['dpsi_heading']:.3f} machine_ref_us={ref:.2f}"
        )
    return 0


def chain_row(robots: int, duration: float) -> dict[str, float]:
    """The full chain at ``robots`` beside the same seed without firmware; printed."""
    plain = firmware_chain.run(robots, duration, firmware=False)
    sil = firmware_chain.run(robots, duration, firmware=True)
    cpu = ", ".join(f"{k} {v:.0f}" for k, v in sorted(sil["cpu"].items(), key=lambda kv: -kv[1]))
    print(f"chain {robots} robots: rtf {sil['rtf']:.3f} (without firmware {plain['rtf']:.3f}); "
          f"CPU % of a core: {cpu}", flush=True)  # fmt: skip
    return {
        "robots": robots,
        "rtf": sil["rtf"],
        "rtf_nofw": plain["rtf"],
        "psi": sil["psi"],
        "psi_nofw": plain["psi"],
        "dpsi": abs(sil["psi"] - plain["psi"]),
        "psi_heading": sil["psi_heading"],
        "psi_heading_nofw": plain["psi_heading"],
        "dpsi_heading": abs(sil["psi_heading"] - plain["psi_heading"]),
    }


if __name__ == "__main__":
    sys.exit(main())
