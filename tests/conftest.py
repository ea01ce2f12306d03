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
