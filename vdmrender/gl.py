"""OpenGL plumbing: a headless EGL context, GLSL loading with #include, the float render target.

Techniques write linear radiance to an RGBA32F target (alpha = coverage), so non-finite
pixels are counted honestly and the sRGB encoding is the same numpy code for technique
and reference.
"""
from __future__ import annotations

import importlib.resources
import os
import re

import numpy as np

from vdmbake.errors import InputError

SHADERS = importlib.resources.files("vdmrender") / "shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)


def create_context(device: str | None = None):
    """A standalone OpenGL 4.3+ context through EGL. `device` (or $VDM_GL_DEVICE) picks the EGL device index."""
    import moderngl

    device = device if device not in (None, "") else os.environ.get("VDM_GL_DEVICE", "")
    kwargs = {}
    if device != "":
        if not str(device).isdigit():
            raise InputError(f"--device / VDM_GL_DEVICE: {device!r} is not an EGL device index (0, 1, ...).")
        kwargs["device_index"] = int(device)
    try:
        return moderngl.create_context(standalone=True, backend="egl", require=430, **kwargs)
    except Exception as e:  # moderngl and glcontext raise plain Exceptions here
        raise InputError(
            f"cannot create an OpenGL 4.3 context through EGL ({e}). On a machine without a GPU, install "
            "Mesa's EGL and llvmpipe (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1); "
            "with several GPUs, pick one with --device N or VDM_GL_DEVICE=N.") from None


def renderer_name(ctx) -> str:
    return f"{ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})"


def source(name: str) -> str:
    """A shader file's text with #include "file" expanded from shaders/include/ (once each)."""
    seen: set[str] = set()

    def expand(text: str) -> str:
        def one(m):
            inc = m.group(1)
            if inc in seen:
                return ""
            seen.add(inc)
            return expand((SHADERS / "include" / inc).read_text())
        return _INCLUDE.sub(one, text)

    return expand((SHADERS / name).read_text())


def program(ctx, vertex: str, fragment: str):
    """Compiled once per context, and only when a technique of the scene asks for it."""
    if ctx.extra is None:
        ctx.extra = {}
    key = (vertex, fragment)
    if key not in ctx.extra:
        ctx.extra[key] = ctx.program(vertex_shader=source(vertex), fragment_shader=source(fragment))
    return ctx.extra[key]


def mat(m: np.ndarray) -> bytes:
    """A float64 4x4 matrix as the column-major float32 bytes GLSL expects."""
    return np.ascontiguousarray(np.asarray(m, np.float64).T, dtype=np.float32).tobytes()


def set_shading(prog, light, material) -> None:
    """The shared shading model's uniforms (shaders/include/shading.glsl)."""
    prog["u_light_dir"].value = tuple(light.direction)
    prog["u_light_color"].value = tuple(light.color)
    prog["u_ambient"].value = tuple(light.ambient)
    prog["u_albedo"].value = tuple(material.albedo)
    prog["u_kd"].value = material.diffuse
    prog["u_ks"].value = material.specular
    prog["u_shininess"].value = material.shininess


class Target:
    """An RGBA32F colour + 32-bit float depth framebuffer of the frame's size."""

    def __init__(self, ctx, width: int, height: int):
        self.ctx, self.size = ctx, (width, height)
        self.color = ctx.renderbuffer((width, height), 4, dtype="f4")
        self.depth = ctx.depth_renderbuffer((width, height))
        self.fbo = ctx.framebuffer([self.color], self.depth)

    def begin(self):
        self.fbo.use()
        self.ctx.viewport = (0, 0, *self.size)
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)

    def read(self) -> np.ndarray:
        """(H, W, 4) float32, row 0 at the top: linear RGB and coverage."""
        w, h = self.size
        a = np.frombuffer(self.fbo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)
        return a[::-1].copy()

    def release(self):
        for o in (self.fbo, self.color, self.depth):
            o.release()
