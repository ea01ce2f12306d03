"""Every test runs with strict GL (vdmrender.gl.strict): a uniform or vertex attribute that a shader
does not have fails the test instead of being skipped. Set here, before any test imports the renderer,
so the CLI runs under CliRunner and in subprocesses are strict too."""
import os

os.environ["VDM_GL_STRICT"] = "1"

import pytest  # noqa: E402


@pytest.fixture(scope="module")
def ctx():
    """One headless GL context per test module (vdmrender.gl: EGL, llvmpipe where there is no GPU)."""
    from vdmrender import gl

    c = gl.create_context()
    yield c
    c.release()


@pytest.fixture
def no_warm_up(monkeypatch):
    """No warm-up before timing (vdmrender.timing.warm_up, as the rows and the benches' interleaved loops call
    it, with warmup = 0 and warmup_s = 0). The bench smoke tests prove a bench's plumbing; waiting for llvmpipe's
    frame times to agree (up to warmup_max_s per variant on a loaded machine) proves nothing there, and the
    warm-up rule itself is test_timing's."""
    from dataclasses import replace

    from vdmrender import timing

    warm_up = timing.warm_up
    monkeypatch.setattr(timing, "warm_up", lambda timer, renderer, cams, budget:
                        warm_up(timer, renderer, cams, replace(budget, warmup=0, warmup_s=0.0)))
