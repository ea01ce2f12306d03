"""Every test runs with strict GL (vdmrender.gpu.gl.strict): a uniform or vertex attribute that a shader
does not have fails the test instead of being skipped. Set here, before any test imports the renderer,
so the CLI runs under CliRunner and in subprocesses are strict too. Also the fixtures several test files
share and the order make test runs the files in (docs/testing.md)."""
import os

os.environ["VDM_GL_STRICT"] = "1"

import pytest  # noqa: E402


def pytest_collection_modifyitems(items):
    """The files holding a slow test first, each file's tests in their order: under make test (xdist, a file to a
    worker, --no-loadscope-reorder) the long files start at once and the short ones fill in behind them, rather than
    one starting last beside an idle worker."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)


@pytest.fixture(scope="module")
def ctx():
    """One headless GL context per test module (vdmrender.gpu.gl: EGL, llvmpipe where there is no GPU)."""
    from vdmrender.gpu import gl

    c = gl.create_context()
    yield c
    c.release()


@pytest.fixture
def no_warm_up(monkeypatch):
    """No warm-up before timing (vdmrender.measuring.timing.warm_up, as the rows and the one interleaved loop that the
    benches time through call it, with warmup = 0 and warmup_s = 0). The bench smoke tests prove a bench's plumbing; waiting for llvmpipe's
    frame times to agree (up to warmup_max_s per variant on a loaded machine) proves nothing there, and the
    warm-up rule itself is test_timing's."""
    from dataclasses import replace

    from vdmrender.measuring import timing

    warm_up = timing.warm_up
    monkeypatch.setattr(timing, "warm_up", lambda timer, renderer, cams, budget:
                        warm_up(timer, renderer, cams, replace(budget, warmup=0, warmup_s=0.0)))


@pytest.fixture(scope="session")
def gl_context_ok():
    """vdmrender error cases that are reached only after the GL context is made need EGL (llvmpipe works)."""
    from vdmbake.errors import InputError
    from vdmrender.gpu import gl

    try:
        ctx = gl.create_context(None)
    except InputError as e:
        pytest.skip(f"no OpenGL 4.3 context through EGL here: {e}")
    ctx.release()


@pytest.fixture
def bundles(tmp_path):
    """Two bundles of two scenes to export from: (this one, another one)."""
    from exports import two_bundles

    return two_bundles(tmp_path)
