"""What one variant costs, measured the same way for every row of a report (per object and composite):
its GPU time by timer queries (vdmrender.measuring.timing), the GPU's clocks around the timing where NVML is there
(vdmrender.gpu.device: a clock that moved means the time did not hold), its work in device-independent
counters (vdmrender.measuring.counters: one more frame per camera from an instrumented build), and its frames read
back for scoring: as shipped, under the run's anti-aliasing mode (vdmrender.measuring.antialias; what is timed and
counted), and point-sampled, one sample per pixel (the `aliased_*` error beside the filtered one)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import antialias, counters, timing
from ..gpu import device, gl


def is_light_pass(name: str) -> bool:
    """The shadow map's pass ("shadow"; "OBJECT shadow" in a composite)."""
    return name == "shadow" or name.endswith(" shadow")


@dataclass
class Harness:
    """One run's GL context, frame target, timer and budget, shared by every variant it measures."""
    ctx: object
    target: gl.Target           # the frame's size, one sample per pixel
    budget: timing.Budget
    count: bool = True          # also count each variant's work (an instrumented build, one frame per camera)
    aa: str = "none"            # the anti-aliasing mode variants are timed, counted and scored in (vdmbake.scene.ANTIALIAS)

    def __post_init__(self):
        self.shipped = self.target if self.aa == "none" else antialias.target(self.ctx, *self.target.size, self.aa)
        self.timer = timing.FrameTimer(self.ctx, self.shipped)
        self.plain = timing.FrameTimer(self.ctx, self.target)
        self.clears = []

    def as_shipped(self, renderer):
        """The renderer as the run ships it: drawing into the anti-aliased target, then its resolve."""
        return renderer if self.aa == "none" else antialias.Resolved(renderer)

    def clear_ms(self) -> float | None:
        """The harness's clear of the target (timed after each variant's sampling, while the clocks are as
        warm as the variants'; median over variants): not charged to any technique."""
        return round(float(np.median(self.clears)), 4) if self.clears else None

    def measure(self, build: Callable, cams, desc: str) -> tuple[dict, list, list]:
        """Build a renderer, time its frames, read them back, release it: (row fields, frames as shipped, frames
        point-sampled: the same list without anti-aliasing)."""
        renderer = build()
        try:
            before = device.nvml_clocks()
            stats, frames = timing.time_variant(self.timer, self.as_shipped(renderer), cams, self.budget, desc)
            self.clears.append(self.timer.clear_ms())
            after = device.nvml_clocks()
            stats["faces"] = getattr(renderer, "faces", None)
            aliased = frames if self.aa == "none" else [self.plain.read(renderer, c, k) for k, c in enumerate(cams)]
        finally:
            renderer.release()
        if self.count:
            stats["counters"], stats["counters_per_pass"], stats["per_pixel"] = self.counted(build, cams)
        if before and after and len(after["gpus"]) == 1:   # with several, NVML's order is not EGL's
            stats["sm_clock_mhz"] = [before["gpus"][0]["sm_clock_mhz"], after["gpus"][0]["sm_clock_mhz"]]
            stats["clock_reasons"] = after["gpus"][0]["clock_reasons"]
        return stats, frames, aliased

    def frames(self, build: Callable, cams) -> list:
        """A renderer's frames as shipped, untimed and uncounted (a full asset that is not a row of its own:
        vdmrender.comparing.change)."""
        renderer = build()
        try:
            shipped = self.as_shipped(renderer)
            return [self.timer.read(shipped, c, k) for k, c in enumerate(cams)]
        finally:
            renderer.release()

    def counted(self, build: Callable, cams) -> tuple[dict, dict, dict]:
        """The variant's work over every camera's frame (exact integers: a --baseline compares them exactly),
        per pass, and per covered pixel over the camera's passes (fragments, fetches and steps: overdraw and
        per-pixel search cost), with the GPU memory it holds."""
        with counters.counting(self.ctx):
            renderer = build()
        try:
            c = counters.count_frames(self.ctx, self.as_shipped(renderer), cams, self.shipped)
            total, passes, covered = c["total"], c["passes"], c["covered"]
            total.update(covered=covered, bytes=counters.resident_bytes(renderer))
        finally:
            renderer.release()
        # per covered pixel, the camera's passes only: the light's pass works at the shadow map's size
        seen = [p for name, p in passes.items() if not is_light_pass(name)]
        per_pixel = {k: round(sum(p[k] for p in seen) / covered, 3) if covered else None
                     for k in ("fragments", "fetches", "steps")}
        return total, passes, per_pixel

    def release(self) -> None:
        if self.shipped is not self.target:
            self.shipped.release()
        self.target.release()
