"""Device-independent cost counters: what a frame costs in work rather than in milliseconds, which llvmpipe
on a shared machine and a GPU measure so differently that times alone compare badly across machines.

One mechanism for every technique (shaders/include/cost_count.glsl): renderers built inside `counting(ctx)`
compile their fragment stages with COUNT (gl.program adds it), which draws the same picture and adds, by
atomics, to four counters in a storage buffer: fragments shaded, texture fetches, search steps and searches.
`count_frame` runs a renderer's passes one by one, reading and zeroing the counters after each, and adds
per pass what GL and moderngl tell without the shaders: primitives (GL_PRIMITIVES_GENERATED), draw calls
and instances drawn; `count_frames` sums them over cameras. `resident_bytes` is the GPU memory the renderer holds.

    with counters.counting(ctx):
        r = variant.build(ctx)
    c = counters.count_frame(ctx, r, camera, target)
    c["total"]["steps"] / c["covered"]        # search steps per covered pixel
"""
from __future__ import annotations

import re
from contextlib import contextmanager

import moderngl
import numpy as np

COUNTERS = ("fragments", "fetches", "steps", "searches")   # cost_count.glsl's order
BINDING = 7                                                # its storage buffer's binding
_MIPMAPPED = {moderngl.NEAREST_MIPMAP_NEAREST, moderngl.LINEAR_MIPMAP_NEAREST, moderngl.NEAREST_MIPMAP_LINEAR,
              moderngl.LINEAR_MIPMAP_LINEAR}


@contextmanager
def counting(ctx):
    """Renderers built inside compile their programs with COUNT (every technique compiles at build time)."""
    if ctx.extra is None:
        ctx.extra = {}
    nested = ctx.extra.get("counting", False)
    ctx.extra["counting"] = True
    try:
        yield
    finally:
        if not nested:
            del ctx.extra["counting"]


def count_frame(ctx, renderer, camera, target) -> dict:
    """One frame of `renderer` (built inside `counting`) into `target`, its passes run one at a time:
    {"passes": {name: counts}, "total": counts, "covered": pixels of the frame with coverage > 0}, counts
    {fragments, fetches, steps, searches, primitives, draws, instances}: the shaders' counters
    (cost_count.glsl), the primitives the vertex stages put out (GL_PRIMITIVES_GENERATED), draw calls and
    instances drawn (GL has no query for these: moderngl's VertexArray.render is wrapped for the frame; a
    draw without instancing is one instance)."""
    if not any("CostCounts" in p for p in gl_objects(renderer) if isinstance(p, moderngl.Program)):
        raise ValueError(f"{type(renderer).__name__}: no program counts; build the renderer inside counters.counting(ctx)")
    if ctx.extra is None:
        ctx.extra = {}
    if "cost counters" not in ctx.extra:   # made once per context: moderngl cannot release a query
        ctx.extra["cost counters"] = (ctx.buffer(reserve=8 * len(COUNTERS)), ctx.query(primitives=True))
    ssbo, query = ctx.extra["cost counters"]
    draws = [0, 0]
    render = moderngl.VertexArray.render

    def counted_render(vao, mode=None, vertices=-1, first=0, instances=-1):
        draws[0] += 1
        draws[1] += max(instances, 1)
        render(vao, mode, vertices, first, instances)

    passes = {}
    moderngl.VertexArray.render = counted_render
    try:
        for name, run in renderer.passes(camera, target):
            ssbo.clear()
            ssbo.bind_to_storage_buffer(BINDING)
            draws[:] = [0, 0]
            with query:
                run()
            ctx.memory_barrier()     # the shaders' atomics visible to the read
            got = dict(zip(COUNTERS, read_counts(ssbo.read())),
                       primitives=int(query.primitives), draws=draws[0], instances=draws[1])
            passes[name] = {k: passes.get(name, {}).get(k, 0) + v for k, v in got.items()}
    finally:
        moderngl.VertexArray.render = render
    total = {k: sum(p[k] for p in passes.values()) for k in (*COUNTERS, "primitives", "draws", "instances")}
    return {"passes": passes, "total": total, "covered": int((target.read()[..., 3] > 0).sum())}


def read_counts(data: bytes) -> list[int]:
    """The counters from their storage buffer's bytes: each a low and a high 32-bit word (cost_count.glsl)."""
    words = np.frombuffer(data, np.uint32).astype(np.int64)
    n = len(COUNTERS)
    return [int(lo) + (int(hi) << 32) for lo, hi in zip(words[:n], words[n:2 * n])]


def count_frames(ctx, renderer, cams, target) -> dict:
    """count_frame over every camera, `target` (a gl.Target) cleared before each frame and drawn into as kept:
    {"total": counts, "passes": {name: counts}, "covered": pixels}, each summed over the cameras."""
    out = {"total": {}, "passes": {}, "covered": 0}
    for cam in cams:
        target.clear()
        c = count_frame(ctx, renderer, cam, target.kept())
        out["covered"] += c["covered"]
        for into, counts in [(out["total"], c["total"]),
                             *((out["passes"].setdefault(name, {}), p) for name, p in c["passes"].items())]:
            for k, v in counts.items():
                into[k] = into.get(k, 0) + v
    return out


def resident_bytes(renderer) -> int:
    """Bytes of the GPU buffers and textures `renderer` holds (its attributes, their lists, tuples, dicts and
    vdmrender objects, each GL object once; framebuffers' attachments too): a buffer's size; a texture's
    texels times components times bytes per component (depth: 4 bytes), its mipmap chain where it is
    filtered through one; after a frame, the per-frame targets a renderer keeps (e.g. the hierarchical
    billboards' depth and occupancy pre-passes)."""
    return sum(texture_bytes(o) if not isinstance(o, moderngl.Buffer) else o.size for o in gl_objects(renderer)
               if isinstance(o, (moderngl.Buffer, moderngl.Texture, moderngl.TextureArray, moderngl.Texture3D,
                                 moderngl.TextureCube, moderngl.Renderbuffer)))


def texture_bytes(t) -> int:
    """Bytes of one texture or renderbuffer (resident_bytes' rule)."""
    texel = t.components * (4 if getattr(t, "depth", None) is True else int(re.sub(r"\D", "", t.dtype)))
    if isinstance(t, moderngl.TextureCube):
        return 6 * t.size[0] * t.size[1] * texel
    if isinstance(t, moderngl.Renderbuffer):
        return t.width * t.height * max(t.samples, 1) * texel
    sides = (t.width, t.height, *((t.depth,) if isinstance(t, moderngl.Texture3D) else ()))
    texels = int(np.prod(sides))
    if t.filter[0] in _MIPMAPPED:   # the chain build_mipmaps made: each level halves every side (not layers)
        while max(sides) > 1:
            sides = tuple(max(s // 2, 1) for s in sides)
            texels += int(np.prod(sides))
    layers = t.layers if isinstance(t, moderngl.TextureArray) else 1
    return texels * layers * texel * (max(t.samples, 1) if isinstance(t, moderngl.Texture) else 1)


def gl_objects(root, skip: tuple = ()) -> list:
    """The moderngl objects reachable from `root` through the attributes of vdmrender objects, lists,
    tuples, sets, dict values and framebuffer attachments, each once (the context is not walked, nor instances
    of the types in `skip`)."""
    found, seen, todo = [], set(), [root]
    while todo:
        o = todo.pop()
        if id(o) in seen or isinstance(o, skip):
            continue
        seen.add(id(o))
        if isinstance(o, (list, tuple, set, frozenset)):
            todo += o
        elif isinstance(o, dict):
            todo += o.values()
        elif isinstance(o, moderngl.Framebuffer):
            found.append(o)
            todo += [*o.color_attachments, o.depth_attachment]
        elif type(o).__module__.startswith("moderngl") and not isinstance(o, moderngl.Context):
            found.append(o)
        elif type(o).__module__.startswith("vdmrender") and hasattr(o, "__dict__"):
            todo += vars(o).values()
    return found
