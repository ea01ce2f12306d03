"""Every test runs with strict GL (vdmrender.gl.strict): a uniform or vertex attribute that a shader
does not have fails the test instead of being skipped. Set here, before any test imports the renderer,
so the CLI runs under CliRunner and in subprocesses are strict too."""
import os

os.environ["VDM_GL_STRICT"] = "1"
