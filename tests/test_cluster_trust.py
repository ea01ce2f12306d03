"""A scheduler address is input (issue 32): local:N bounded as --jobs; an address where nothing listens refused
within seconds, one where another service answers refused as no scheduler (exit 2, one paragraph); a scheduler
lost mid-run ends in the closing table with the scenes not finished named, no traceback (exit 1)."""
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from test_batch import SLOW, SMALL, _wait_for_staging, write
from vdmbake.cli import main as bake_main
from vdmbake.library import cluster

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


def test_a_scheduler_lost_mid_run_ends_in_the_closing_table(tmp_path):
    """Failed before the fix: 'Client lost the connection' once per scene and a traceback. Now the scenes not
    finished are named in the closing table, exit 1, no traceback."""
    env = {k: v for k, v in os.environ.items() if k != "VDM_CACHE"}
    info = tmp_path / "scheduler.json"
    sched = subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                              "--scheduler-file", str(info)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             env=env)
    worker = None
    try:
        for _ in range(300):
            if info.is_file() and info.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:"), address                  # on the loopback only
        worker = subprocess.Popen([str(BIN / "dask"), "worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                                   "--nworkers", "1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL, env=env)
        write(tmp_path / "s", **{f"slow{i}": SLOW for i in range(4)})
        out = tmp_path / "out"
        p = subprocess.Popen([str(BIN / "vdmbake"), str(tmp_path / "s"), "-o", str(out), "--scheduler", address],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        _wait_for_staging(out, p, timeout=120)
        sched.send_signal(signal.SIGKILL)
        stdout, stderr = p.communicate(timeout=120)
    finally:
        for q in (sched, worker):
            if q is not None and q.poll() is None:
                q.kill()
                q.wait()
    assert p.returncode == 1, (stdout, stderr)
    assert "Traceback" not in stderr and "Traceback" not in stdout, stderr[-3000:]
    assert "not finished: the connection to the Dask scheduler" in stdout, stdout
    assert "4 scenes:" in stdout and stderr.count("Client lost the connection") == 0, stderr[-3000:]
