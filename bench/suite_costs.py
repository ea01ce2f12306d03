"""A pytest plugin (bench.suite loads it as `-p vdm_suite_costs`): each test's CPU seconds, as its process counts
them: the process's own threads (llvmpipe's and Embree's included) and the children it reaped meanwhile
(subprocesses, local clusters), and whether it failed (in setup, call or teardown), one JSON line per test into
$VDM_SUITE_COSTS/PID.jsonl. The standard library and
pytest only, so it loads into the suite of any commit."""
import json
import os
import resource
import time

import pytest

_failed: set[str] = set()


def _cpu() -> float:
    own, reaped = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + reaped.ru_utime + reaped.ru_stime


def pytest_runtest_logreport(report):
    if report.failed:
        _failed.add(report.nodeid)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    c0, t0 = _cpu(), time.perf_counter()
    yield
    row = {"id": item.nodeid, "cpu_s": round(_cpu() - c0, 3), "wall_s": round(time.perf_counter() - t0, 3),
           "slow": item.get_closest_marker("slow") is not None, "failed": item.nodeid in _failed}
    with open(os.path.join(os.environ["VDM_SUITE_COSTS"], f"{os.getpid()}.jsonl"), "a") as f:
        f.write(json.dumps(row) + "\n")
