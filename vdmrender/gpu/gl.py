"""OpenGL plumbing: a headless EGL context, GLSL loading with #include, the float render target.

Techniques write linear radiance to an RGBA32F target (alpha = coverage), so non-finite
pixels are counted honestly and the sRGB encoding is the same numpy code for technique
and reference.
"""
from __future__ import annotations

import importlib.resources
import os
import re

import moderngl
import numpy as np

from vdmbake.common import texture
from vdmbake.errors import InputError

SHADERS = importlib.resources.files("vdmrender") / "shaders"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.M)

# Strict GL: a uniform or vertex attribute that a program does not have is an error, not silently
# skipped (a renamed uniform would otherwise show only as drift in the error). On under --debug and
# wherever $VDM_GL_STRICT is set (tests/conftest.py sets it for every test).
STRICT = False


class GLError(RuntimeError):
    """A program and the data given to it disagree (raised in strict mode)."""


def strict() -> bool:
    return STRICT or os.environ.get("VDM_GL_STRICT", "") not in ("", "0")


def create_context(device: str | None = None):
    """A standalone OpenGL 4.3+ context through EGL. `device` (or $VDM_GL_DEVICE): an EGL device index N, or
    cuda:N, the GPU CUDA numbers N (vdmrender.gpu.device)."""
    from .device import egl_device_index

    spec = device if device not in (None, "") else os.environ.get("VDM_GL_DEVICE", "")
    index = egl_device_index(spec)
    kwargs = {} if index is None else {"device_index": index}
    try:
        return moderngl.create_context(standalone=True, backend="egl", require=430, **kwargs)
    except Exception as e:  # moderngl and glcontext raise plain Exceptions here
        raise InputError(
            f"cannot create an OpenGL 4.3 context through EGL ({e}). On a machine without a GPU, install "
            "Mesa's EGL and llvmpipe (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1); "
            "with several GPUs, pick one with --device N (EGL's order) or --device cuda:N (CUDA's), or "
            "VDM_GL_DEVICE.") from None


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


def program(ctx, vertex: str, fragment: str, defines: tuple[str, ...] = (), may_lack: tuple[str, ...] = ()):
    """Compiled once per context, and only when a technique of the scene asks for it.
    `defines` select a pass variant of a stage (e.g. DIRECT, GBUFFER). `may_lack`: the uniforms and
    vertex attributes this pass variant legitimately compiles away (set_uniforms and vertex_array
    then skip them even when strict); name them here, next to the defines that drop them.
    While counting is on for the context (vdmrender.measuring.counters.counting), the fragment stage is compiled
    with COUNT too (shaders/include/cost_count.glsl: the same picture, plus atomics adding to the cost
    counters; it reads the same uniforms, so strictness holds for it as for the normal build)."""
    if ctx.extra is None:
        ctx.extra = {}
    fragment_defines = (*defines, *(("COUNT",) if ctx.extra.get("counting") else ()))
    key = (vertex, fragment, *fragment_defines)
    if key not in ctx.extra:
        variant = f" [{', '.join(fragment_defines)}]" if fragment_defines else ""
        try:
            prog = ctx.program(vertex_shader=_with_defines(source(vertex), defines),
                               fragment_shader=_with_defines(source(fragment), fragment_defines))
        except moderngl.Error as e:
            raise InputError(f"{vertex} + {fragment}{variant}: the shaders do "
                             f"not compile on {renderer_name(ctx)} (an overridden GL version, e.g. "
                             f"MESA_GL_VERSION_OVERRIDE, or a driver lacking GLSL 4.30?). Compiler log:\n{e}") from None
        prog.extra = {"name": f"{vertex} + {fragment}{variant}", "may_lack": frozenset(may_lack),
                      "units": {n: i for i, n in enumerate(samplers(prog))}}
        ctx.extra[key] = prog
    prog = ctx.extra[key]
    if prog.extra["may_lack"] != frozenset(may_lack):
        raise GLError(f"{prog.extra['name']}: built with may_lack {sorted(prog.extra['may_lack'])}, "
                      f"asked again with {sorted(may_lack)}")
    return prog


def _info(prog) -> dict:
    """What gl.program recorded on the program (its name, may_lack); defaults for others."""
    return prog.extra or {"name": "program", "may_lack": frozenset()}


def _lacks(prog, name: str, what: str) -> bool:
    """True if `prog` has no active `name`; an error when strict unless the program declared it."""
    if name in prog:
        return False
    info = _info(prog)
    if strict() and name not in info["may_lack"]:
        raise GLError(f"{info['name']}: no active {what} {name!r} (renamed, misspelt, or unused by the "
                      "shader; declare it in gl.program(..., may_lack=...) if a pass variant drops it)")
    return True


_ONE_INT = (0x1404, 0x8B56)   # GL_INT, GL_BOOL: the uniforms besides samplers that hold one integer


def samplers(prog) -> list[str]:
    """The program's sampler uniforms in name order; bind_textures gives the i-th texture unit i."""
    return sorted(n for n in prog if isinstance(prog[n], moderngl.Uniform) and prog[n].fmt == "1i"
                  and prog[n].gl_type not in _ONE_INT)


def bind_textures(prog, **textures) -> None:
    """Bind textures to samplers by name: each sampler reads a texture unit of its own, fixed per program
    (its place in `samplers`), so no caller numbers units. A name the program lacks is skipped if
    declared in may_lack (or when not strict), an error otherwise."""
    units = _info(prog).get("units") or {n: i for i, n in enumerate(samplers(prog))}
    for name, tex in textures.items():
        if not _lacks(prog, name, "sampler"):
            tex.use(units[name])
            prog[name].value = units[name]


def set_uniforms(prog, **values) -> None:
    """Set uniforms by name; one the program lacks is skipped if declared in may_lack (or when not
    strict), an error otherwise. A 4x4 array is a matrix (row-major here, column-major in GLSL); any
    other array is written as it lies in memory (int32 for integer and bool arrays, float32 otherwise),
    e.g. a uniform array of ivec2 or of matrices the caller laid out column-major."""
    for name, value in values.items():
        if _lacks(prog, name, "uniform"):
            continue
        if isinstance(value, np.ndarray) and value.shape == (4, 4):
            prog[name].write(mat(value))
        elif isinstance(value, np.ndarray):
            prog[name].write(np.ascontiguousarray(value, np.int32 if value.dtype.kind in "iub" else np.float32).tobytes())
        else:
            prog[name].value = value


_TOKEN = re.compile(r"(\d*)([fiux])(\d?)")
_BYTES = {"f": 4, "i": 4, "u": 4, "x": 1}


def vertex_array(ctx, prog, content: list, index=None, subset: bool = False):
    """ctx.vertex_array whose layout must match the program: every attribute given is one the
    program has (those it declared in may_lack become padding bytes of the same size), with the
    format's component count equal to the attribute's, and every attribute the program reads is
    given. A mismatch is an error when strict (otherwise lacking attributes are padded). subset: the
    program reads only some of the attributes (a depth pass over its frame pass's layout, which the
    frame pass checks): the others become padding, derived from their formats."""
    given, fixed = set(), []
    for buf, fmt, *names in content:
        spec, _, per = fmt.partition("/")
        tokens, it = [], iter(names)
        for tok in spec.split():
            m = _TOKEN.fullmatch(tok)
            n, kind, size = int(m.group(1) or 1), m.group(2), int(m.group(3) or _BYTES[m.group(2)])
            if kind == "x":
                tokens.append(tok)
                continue
            name = next(it)
            given.add(name)
            if (subset and name not in prog) or _lacks(prog, name, "vertex attribute"):
                tokens.append(f"{n * size}x")
                names = [x for x in names if x != name]
                continue
            if strict() and prog[name].dimension != n:
                raise GLError(f"{_info(prog)['name']}: vertex attribute {name!r} has {prog[name].dimension} "
                              f"components, the layout {fmt!r} gives {n}")
            tokens.append(tok)
        if names:    # a buffer whose every attribute was dropped is not bound at all
            fixed.append((buf, " ".join(tokens) + (f"/{per}" if per else ""), *names))
    import moderngl

    unfed = [n for n in prog if isinstance(prog[n], moderngl.Attribute) and n not in given
             and not n.startswith("gl_")]
    if unfed and strict():
        raise GLError(f"{_info(prog)['name']}: vertex attributes {unfed} are read but not given")
    return ctx.vertex_array(prog, fixed, index)


def quad_corners(ctx):
    """A buffer of a screen-aligned quad's corners (+-1, +-1) as a triangle strip: the in_corner of the stages that
    cover a projected bound (sphere.vert, cylinder.vert, bounding_quad.vert)."""
    return ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, 1, 1], "f4").tobytes())


def release(*objects) -> None:
    """Release GL objects (vertex arrays, buffers, textures, framebuffers, shadow maps); None is skipped."""
    for o in objects:
        if o is not None:
            o.release()


def mat(m: np.ndarray) -> bytes:
    """A float64 4x4 matrix as the column-major float32 bytes GLSL expects."""
    return np.ascontiguousarray(np.asarray(m, np.float64).T, dtype=np.float32).tobytes()


def set_shading(prog, light, material, albedo: bool = True) -> None:
    """The shared shading model's uniforms (shaders/include/shading.glsl) and, if `albedo`, the
    object's albedo as u_albedo (stages that take colours per instance or from a G-buffer have none)."""
    set_uniforms(prog, u_light_dir=tuple(light.direction), u_light_color=tuple(light.color),
                 u_ambient=tuple(light.ambient), u_kd=material.diffuse, u_ks=material.specular,
                 u_shininess=material.shininess, **({"u_albedo": tuple(material.albedo)} if albedo else {}))


def check_size(ctx, size: tuple[int, int], what: str, fix: str, *limits: str) -> None:
    """Refuse a texture or target of `size` (width, height) over the device's own `limits` (names in ctx.info,
    e.g. GL_MAX_TEXTURE_SIZE) before it is made: beyond them moderngl raises, or a texture samples as black."""
    for name in limits:
        most = min(np.atleast_1d(ctx.info[name]))   # GL_MAX_VIEWPORT_DIMS is a pair
        if max(size) > most:
            raise InputError(f"{what} of {size[0]} x {size[1]} is over {renderer_name(ctx)}'s {name} of {most}; "
                             f"{fix}.")


def albedo_texture(ctx, albedo_map: np.ndarray, mipmaps: bool = False):
    """An albedo map (vdmbake.common.texture: uint8 sRGB, row 0 at v = 0) as a texture read as its numpy twin reads
    it: the texels decoded to linear (half floats), linear filtering, wrap-around, no mipmaps. mipmaps (the scene's
    render.mipmaps): a mip chain and trilinear filtering, the pixel's footprint averaged as a filtered reference
    averages it. The chain is built from the linear texels, so each level is the mean reflectance the reference's
    samples would average, not the mean of sRGB codes. No anisotropic filtering: moderngl sets it and llvmpipe
    (Mesa 22.3) offers 16x, but its anisotropic path filters magnified texels too (a checker magnified 2.6x came
    out up to 0.34 off the bilinear frame: tests/test_mipmaps.py), which would blur every close-up."""
    h, w = albedo_map.shape[:2]
    check_size(ctx, (w, h), "the albedo map", "re-bake it with a smaller picture (vdmbake keeps a side within 16384, "
               "the least GL 4.5 allows)", "GL_MAX_TEXTURE_SIZE")
    tex = ctx.texture((w, h), 3, np.ascontiguousarray(texture.linear(albedo_map), np.float16).tobytes(),
                      dtype="f2", alignment=1)
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = True
    if mipmaps:
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    return tex


class Target:
    """An RGBA32F colour + 32-bit float depth framebuffer of the frame's size. begin() binds and clears it
    (a technique drawing alone); kept() is the same target seen by a harness that clears it itself."""

    def __init__(self, ctx, width: int, height: int):
        self.ctx, self.size = ctx, (width, height)
        self.color = ctx.renderbuffer((width, height), 4, dtype="f4")
        self.depth = ctx.depth_renderbuffer((width, height))
        self.fbo = ctx.framebuffer([self.color], self.depth)

    def bind(self):
        self.fbo.use()
        self.ctx.viewport = (0, 0, *self.size)

    def clear(self):
        self.bind()
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)

    begin = clear

    def kept(self) -> "Kept":
        return Kept(self)

    def read(self) -> np.ndarray:
        """(H, W, 4) float32, row 0 at the top: linear RGB and coverage."""
        w, h = self.size
        a = np.frombuffer(self.fbo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)
        return a[::-1].copy()

    def release(self):
        release(self.fbo, self.color, self.depth)


class Kept:
    """A Target as techniques see it where someone else clears it: begin() binds without clearing. The
    timing harness clears outside the timed passes (the clear is not a technique's cost); a composite
    frame clears once and every object draws into it."""

    def __init__(self, target: Target):
        self.target, self.ctx, self.size, self.fbo = target, target.ctx, target.size, target.fbo

    def begin(self):
        self.target.bind()

    def kept(self) -> "Kept":
        return self

    def read(self) -> np.ndarray:
        return self.target.read()
