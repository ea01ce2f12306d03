"""Frames anti-aliased as they would be shipped (render.antialias, `vdmrender --antialias`): the target a
variant draws into, and the resolve to one colour per pixel, timed as a pass of the frame.

* `msaaN`: GL multisampling, N coverage and depth samples per pixel and one fragment-stage run per pixel
  and primitive; resolved by a blit (the mean of the samples). It smooths the edges of rasterised triangles;
  the silhouettes a fragment stage makes by discarding or by writing its own depth (impostors, billboards,
  octahedral impostors) and a deferred pass's pixels stay aliased, which the error then shows.
* `ssaaK`: the frame rendered K x K times larger (a target of K W x K H; the cameras keep the display's
  size, so screen-size choices such as a LOD chain's see the display) and box-filtered down on the GPU in
  linear colour (shaders/resolve.frag): every technique's every pass is anti-aliased, at about K^2 the cost.

Both targets keep the gl.Target interface the harness and the renderers use (clear, kept, begin, size, read),
and `Resolved` appends the resolve to a renderer's passes, so the timer and the cost counters charge it to
the variant like any pass. The colour is premultiplied by coverage, as the filtered reference's
(vdmrender.tracing.reference.filtered)."""
from __future__ import annotations

import moderngl

from vdmbake.errors import InputError
from vdmbake.scene import ANTIALIAS

from ..gpu import gl


# The device's limits a target's size is checked against (besides a texture's GL_MAX_TEXTURE_SIZE), before it is made.
LIMITS = ("GL_MAX_RENDERBUFFER_SIZE", "GL_MAX_VIEWPORT_DIMS")


class Multisampled:
    """An RGBA32F + depth framebuffer with N samples per pixel, resolved into a gl.Target of the same size."""

    def __init__(self, ctx, width: int, height: int, samples: int):
        if samples > ctx.max_samples:
            raise InputError(f"--antialias msaa{samples}: {gl.renderer_name(ctx)} allows at most {ctx.max_samples} "
                             f"samples per pixel; choose msaa{ctx.max_samples} or fewer, or ssaaK.")
        self.ctx, self.size = ctx, (width, height)
        gl.check_size(ctx, self.size, f"--antialias msaa{samples}: the multisampled target", "choose a smaller "
                      "resolution", *LIMITS)
        self.color = ctx.renderbuffer((width, height), 4, samples=samples, dtype="f4")
        self.depth = ctx.depth_renderbuffer((width, height), samples=samples)
        self.fbo = ctx.framebuffer([self.color], self.depth)
        self.out = gl.Target(ctx, width, height)

    def resolve(self) -> None:
        self.ctx.copy_framebuffer(self.out.fbo, self.fbo)

    def release(self) -> None:
        gl.release(self.fbo, self.color, self.depth)
        self.out.release()


class Supersampled:
    """An RGBA32F texture + depth framebuffer K times the frame's size each way, resolved into a gl.Target of
    the frame's size by the K x K box filter of shaders/resolve.frag."""

    def __init__(self, ctx, width: int, height: int, k: int):
        self.ctx, self.k, self.size = ctx, k, (k * width, k * height)
        gl.check_size(ctx, self.size, f"--antialias ssaa{k} at {width} x {height}: the supersampled target",
                      f"choose a smaller K or resolution (K x each side at most {ctx.info['GL_MAX_TEXTURE_SIZE']})",
                      *LIMITS, "GL_MAX_TEXTURE_SIZE")
        self.color = ctx.texture(self.size, 4, dtype="f4")
        self.color.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.depth = ctx.depth_renderbuffer(self.size)
        self.fbo = ctx.framebuffer([self.color], self.depth)
        self.out = gl.Target(ctx, width, height)
        self.prog = gl.program(ctx, "fullscreen.vert", "resolve.frag")
        self.vao = gl.vertex_array(ctx, self.prog, [])

    def resolve(self) -> None:
        self.out.bind()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE)
        gl.bind_textures(self.prog, u_frame=self.color)
        gl.set_uniforms(self.prog, u_k=self.k)
        self.vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        gl.release(self.vao, self.fbo, self.color, self.depth)
        self.out.release()


class Target(gl.Target):
    """The harness's target under an anti-aliasing mode: a gl.Target (bound, cleared and begun as one) whose
    framebuffer holds the mode's samples, cleared there outside the timed passes, read after the resolve."""

    def __init__(self, ctx, width: int, height: int, mode: str):
        self.ctx, self.mode = ctx, mode
        kind, n = ANTIALIAS[mode]
        self.buffers = (Multisampled if kind == "msaa" else Supersampled)(ctx, width, height, n)
        self.size, self.fbo = self.buffers.size, self.buffers.fbo

    def kept(self) -> "Kept":
        return Kept(self)

    def resolve(self) -> None:
        self.buffers.resolve()

    def read(self):
        """The resolved frame: (H, W, 4) float32, row 0 at the top, premultiplied linear RGB and coverage."""
        return self.buffers.out.read()

    def release(self) -> None:
        self.buffers.release()


class Kept(gl.Kept):
    """An anti-aliased Target as renderers see it where the harness clears it (gl.Kept), with its resolve."""

    def resolve(self) -> None:
        self.target.resolve()


class Resolved:
    """A renderer drawing into an anti-aliased target: its passes, then the resolve (timed and counted as the
    pass `resolve`)."""

    def __init__(self, renderer):
        self.renderer = renderer

    def passes(self, camera, target) -> list:
        return [*self.renderer.passes(camera, target), ("resolve", target.resolve)]

    def __getattr__(self, attr):
        return getattr(self.renderer, attr)


def target(ctx, width: int, height: int, mode: str):
    """The harness's target for `mode` (vdmbake.scene.ANTIALIAS): a gl.Target for none, else an anti-aliased Target."""
    return gl.Target(ctx, width, height) if mode == "none" else Target(ctx, width, height, mode)
