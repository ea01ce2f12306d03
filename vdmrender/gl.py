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
    """A shader file's text with its includes expanded."""
    return expand((SHADERS / name).read_text())


def expand(text: str) -> str:
    """GLSL text with #include "file" expanded from shaders/include/ (each file once)."""
    seen: set[str] = set()

    def one(m):
        inc = m.group(1)
        if inc in seen:
            return ""
        seen.add(inc)
        return _INCLUDE.sub(one, (SHADERS / "include" / inc).read_text())

    return _INCLUDE.sub(one, text)


def _with_defines(src: str, defines: tuple[str, ...]) -> str:
    first, _, rest = src.partition("\n")  # #version must stay the first line
    return "\n".join([first, *(f"#define {d}" for d in defines), rest])


def program(ctx, vertex: str, fragment: str, defines: tuple[str, ...] = ()):
    """Compiled once per context, and only when a technique of the scene asks for it.
    `defines` select a pass variant of a stage (e.g. DIRECT, GBUFFER)."""
    if ctx.extra is None:
        ctx.extra = {}
    key = (vertex, fragment, *defines)
    if key not in ctx.extra:
        ctx.extra[key] = ctx.program(vertex_shader=_with_defines(source(vertex), defines),
                                     fragment_shader=_with_defines(source(fragment), defines))
    return ctx.extra[key]


def set_uniforms(prog, **values) -> None:
    """Set the uniforms a program has; those its pass variant compiled away are skipped."""
    for name, value in values.items():
        if name in prog:
            if isinstance(value, np.ndarray) and value.shape == (4, 4):
                prog[name].write(mat(value))
            else:
                prog[name].value = value


def release(*objects) -> None:
    """Release GL objects (vertex arrays, buffers, textures, framebuffers, shadow maps); None is skipped."""
    for o in objects:
        if o is not None:
            o.release()


def mat(m: np.ndarray) -> bytes:
    """A float64 4x4 matrix as the column-major float32 bytes GLSL expects."""
    return np.ascontiguousarray(np.asarray(m, np.float64).T, dtype=np.float32).tobytes()


def set_shading(prog, light, material) -> None:
    """The shared shading model's uniforms (shaders/include/shading.glsl) and the object's albedo."""
    set_uniforms(prog, u_light_dir=tuple(light.direction), u_light_color=tuple(light.color),
                 u_ambient=tuple(light.ambient), u_albedo=tuple(material.albedo), u_kd=material.diffuse,
                 u_ks=material.specular, u_shininess=material.shininess)


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
        release(self.fbo, self.color, self.depth)
