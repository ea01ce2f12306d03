"""A scheduler address is input (issue 32): local:N bounded as --jobs; an address where nothing listens refused
within seconds, one where another service answers refused as no scheduler, one without workers refused after
--workers-wait (exit 2, one paragraph); a scheduler lost mid-run ends in the closing table with the scenes not
finished named, no traceback (exit 2), and its workers stop their tasks (issue 41)."""
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from bench.cluster import ENV, scheduler, stop, worker
from batches import SLOW, SMALL, _wait_for_staging, hidden, write
from vdmbake.cli import main as bake_main
from vdmbake import cluster

pytest.importorskip("distributed")
BIN = Path(sys.executable).parent


def _bake(tmp_path, address):
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"))
    return CliRunner().invoke(bake_main, [str(tmp_path / "s"), "-o", str(tmp_path / "out"), "--scheduler", address],
                              env={"VDM_CACHE": None})


def test_local_n_is_bounded_as_jobs(tmp_path):
    """Failed before the fix: local:100000 started worker processes until killed."""
    r = _bake(tmp_path, "local:100000")
    assert r.exit_code == 2 and "local:N needs 1 to 1024 worker processes" in r.output, r.output


def test_a_refused_connection_is_reported_within_seconds(tmp_path, monkeypatch):
    """Failed before the fix: Dask's client made, waiting its 30 s connect timeout, before the same exit 2. Now one
    plain TCP connect bounded by cluster.CONNECT_S refuses the address and Dask's client is never made (shown by
    what is called, not by a wall time)."""
    import dask.distributed

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()                                   # nothing listens there now
    connects, create_connection = [], socket.create_connection

    def connect(address, timeout=None, *args, **kwargs):
        connects.append((address, timeout))
        return create_connection(address, timeout, *args, **kwargs)

    def client(*args, **kwargs):
        raise AssertionError("Dask's client was made (it waits up to its own connect timeout)")
    monkeypatch.setattr(socket, "create_connection", connect)
    monkeypatch.setattr(dask.distributed, "Client", client)
    r = _bake(tmp_path, f"tcp://127.0.0.1:{port}")
    assert r.exit_code == 2 and "cannot reach the Dask scheduler" in r.output, r.output
    assert connects == [(("127.0.0.1", port), cluster.CONNECT_S)] and cluster.CONNECT_S <= 5


def test_another_service_is_no_scheduler(tmp_path):
    """Failed before the fix: a numpy allocation traceback (Dask read 'HTTP/1.1' as a frame's length)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()

    def answer():
        while True:
            try:
                c, _ = server.accept()
            except OSError:
                return
            c.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
            c.close()
    threading.Thread(target=answer, daemon=True).start()
    try:
        r = _bake(tmp_path, f"tcp://127.0.0.1:{server.getsockname()[1]}")
    finally:
        server.close()
    assert r.exit_code == 2 and "Traceback" not in r.output, r.output
    assert "--scheduler tcp://127.0.0.1:" in r.output and "Dask scheduler" in r.output, r.output


def test_no_worker_within_the_wait_is_refused(tmp_path):
    """Failed before the fix: a scheduler without workers made vdmbake wait forever. Now --workers-wait bounds the
    wait: exit 2, the scheduler named, nothing baked. (A process of its own, as a user runs it: a Dask client made
    in this test process after the earlier tests' can fail its handshake.)"""
    write(tmp_path / "s", a=SMALL.format(name="a", prim="sphere"))
    with scheduler(tmp_path) as (address, _):
        r = subprocess.run([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(tmp_path / "out"), "--scheduler",
                            address, "--workers-wait", "1"], capture_output=True, text=True, env=ENV, timeout=120)
    assert r.returncode == 2 and f"--scheduler {address}: no Dask worker joined the scheduler within 1 s" in r.stderr, \
        r.stderr
    assert not (tmp_path / "out" / "a.bundle").exists()


def test_every_worker_lost_mid_run_ends_after_the_wait(tmp_path):
    """The only worker (its nanny and process) killed mid-bake: the scheduler has none for --workers-wait seconds,
    and the run stops there (exit 2) with the scenes not finished named, instead of waiting forever."""
    with scheduler(tmp_path) as (address, _):
        w = worker(address)
        try:
            write(tmp_path / "s", **{f"slow{i}": SLOW for i in range(2)})
            out = tmp_path / "out"
            p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--scheduler", address,
                                  "--workers-wait", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                 env=ENV)
            _wait_for_staging(out, p, timeout=120)
        finally:
            stop(w)
        stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 2, (stdout, stderr)
    assert f"not finished: no Dask worker on the scheduler {address} for 2 s (--workers-wait)" in stdout, stdout
    assert "error: the run stopped: no Dask worker on the scheduler" in stderr and "Traceback" not in stderr, stderr


def test_a_scheduler_lost_mid_run_ends_in_the_closing_table(tmp_path):
    """Failed before the fix: 'Client lost the connection' once per scene and a traceback; then, exit 1 and the
    worker baking on for the nanny's 30 s. Now the scenes not finished are named in the closing table, exit 2, no
    traceback; and the worker stops the bake it holds (without the stop it would finish it: a worker closes when
    its scheduler is lost, but the task's thread runs on until the nanny kills the process 30 s later): no scene
    not finished has a bundle, and no staging folder is left."""
    with scheduler(tmp_path) as (address, sched):
        w = worker(address)
        try:
            write(tmp_path / "s", **{f"slow{i}": SLOW.replace("resolution = 96", "resolution = 512") for i in range(4)})
            out = tmp_path / "out"
            p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--scheduler", address],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
            _wait_for_staging(out, p, timeout=120)
            sched.send_signal(signal.SIGKILL)
            stdout, stderr = p.communicate(timeout=120)
            w.wait(timeout=120)
        finally:
            stop(w)
    assert p.returncode == 2, (stdout, stderr)
    assert "Traceback" not in stderr and "Traceback" not in stdout, stderr[-3000:]
    assert "not finished: the connection to the Dask scheduler" in stdout, stdout
    assert "error: the run stopped: the connection to the Dask scheduler" in stderr, stderr[-3000:]
    assert "4 scenes:" in stdout and stderr.count("Client lost the connection") == 0, stderr[-3000:]
    assert [n for n in hidden(out) if ".tmp-" in n] == [], hidden(out)
    lost = [line.split()[0] for line in stdout.splitlines() if "not finished" in line]
    assert lost and not [s for s in lost if (out / s.replace(".toml", ".bundle")).exists()], (lost, stdout)
