"""``aes-swarm sweep --scheduler tls://…`` on a real Dask cluster that only its CA's members reach.

A scheduler and a worker started the documented way (``dask scheduler --protocol tls
--tls-ca-file … --tls-cert … --tls-key …``) with certificates made here by ``openssl``:

- the sweep through ``tls://`` gives exactly the numbers of the same sweep run locally;
- a client whose certificate another CA signed, and one with no certificate, are refused
  by the scheduler itself (the TLS handshake fails), so they never submit anything.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import ssl
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers.ros_env import wait_for

from aes_ros.cli import main

BIN = Path(sys.executable).parent
SWEEP = [
    "--setup", "linear", "--robots", "9", "--duration", "1", "--runs", "2",
    "--param", "alpha=0.02:0.2:2", "--no-progress",
]  # fmt: skip


def openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def make_ca(cwd: Path, name: str) -> None:
    """``name``.pem, a self-signed CA, and its key ``name``-key.pem."""
    openssl(
        "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
        "-days", "1", "-subj", f"/CN={name}", "-keyout", f"{name}-key.pem", "-out", f"{name}.pem",
        cwd=cwd,
    )  # fmt: skip


def make_member(cwd: Path, ca: str, name: str) -> None:
    """``name``.pem and ``name``-key.pem for 127.0.0.1, signed by the CA ``ca``."""
    openssl(
        "req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
        "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1",
        "-keyout", f"{name}-key.pem", "-out", f"{name}.csr", cwd=cwd,
    )  # fmt: skip
    openssl(
        "x509", "-req", "-in", f"{name}.csr", "-CA", f"{ca}.pem", "-CAkey", f"{ca}-key.pem",
        "-CAcreateserial", "-days", "1", "-copy_extensions", "copy", "-out", f"{name}.pem",
        cwd=cwd,
    )  # fmt: skip


def tls_files(certs: Path, ca: str, member: str) -> list[str]:
    return [
        "--tls-ca", str(certs / f"{ca}.pem"),
        "--tls-cert", str(certs / f"{member}.pem"),
        "--tls-key", str(certs / f"{member}-key.pem"),
    ]  # fmt: skip


@pytest.fixture
def tls_cluster(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """A TLS scheduler on 127.0.0.1 and one worker; yields (address, certificate directory)."""
    if shutil.which("openssl") is None:
        pytest.skip("needs the openssl command")
    certs = tmp_path / "certs"
    certs.mkdir()
    make_ca(certs, "ca")
    make_member(certs, "ca", "member")
    make_ca(certs, "other")
    make_member(certs, "other", "stranger")
    dask_tls = [
        "--tls-ca-file", str(certs / "ca.pem"),
        "--tls-cert", str(certs / "member.pem"),
        "--tls-key", str(certs / "member-key.pem"),
    ]  # fmt: skip
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    file = tmp_path / "scheduler.json"
    procs: list[subprocess.Popen] = []

    def start(*args: str, name: str) -> None:
        log = open(tmp_path / f"{name}.log", "w")
        command = [str(BIN / "dask"), *args, *dask_tls]
        procs.append(
            subprocess.Popen(
                command, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
            )
        )

    try:
        start("scheduler", "--scheduler-file", str(file), "--host", "127.0.0.1", "--port", "0",
              "--protocol", "tls", "--no-dashboard", name="scheduler")  # fmt: skip
        assert wait_for(file.exists, 60), (tmp_path / "scheduler.log").read_text()
        address = json.loads(file.read_text())["address"]
        start("worker", "--scheduler-file", str(file), "--nthreads", "1", "--no-dashboard",
              "--no-nanny", name="worker")  # fmt: skip
        yield address, certs
    finally:
        # the worker first: a worker closing because its scheduler went away hangs on SIGTERM
        for proc in reversed(procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)


def sweep(out: Path, *extra: str) -> int:
    """``aes-swarm sweep`` in this process (the CLI's code, without a start-up per run)."""
    return main(["sweep", *SWEEP, "--out", str(out), *extra])


def test_a_tls_cluster_runs_the_sweep_for_its_members_only(tls_cluster, tmp_path, capsys):
    address, certs = tls_cluster
    assert address.startswith("tls://127.0.0.1:")
    assert sweep(tmp_path / "local") == 0

    assert sweep(tmp_path / "tls", "--scheduler", address, *tls_files(certs, "ca", "member")) == 0
    assert f"on {address}" in capsys.readouterr().out
    for name in ("runs.csv", "points.csv"):
        assert (tmp_path / "tls" / name).read_text() == (tmp_path / "local" / name).read_text()

    # a certificate of another CA: the scheduler ends the handshake, nothing runs
    stranger = tls_files(certs, "ca", "stranger")
    assert sweep(tmp_path / "stranger", "--scheduler", address, *stranger) == 2
    assert f"--scheduler {address}: cannot connect" in capsys.readouterr().err
    assert (tmp_path / "stranger" / "runs.csv").read_text().count("\n") == 1  # the header

    # no client certificate at all: refused by the scheduler, not only by our client
    context = ssl.create_default_context(cafile=str(certs / "ca.pem"))
    context.check_hostname = False
    host, port = address.removeprefix("tls://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=10) as raw:
        try:
            with context.wrap_socket(raw) as conn:  # TLS 1.3: the refusal comes on first read
                conn.sendall(b"\0")
                refused = conn.recv(1) == b""  # closed without a word also refuses
        except (ssl.SSLError, ConnectionError):
            refused = True
    assert refused
