"""Technique `octahedral`: octahedral impostors (Brucks 2018, "Octahedral Impostors"; the impostors of
Unreal's baker as used in Fortnite, and of Amplify Impostors). Each variant names a layout (the full
sphere of view directions, or the hemisphere above world +Z, the scenes' default up), N x N views of
R x R texels in one atlas, and the per-view search (march: a ray / depth-map search; virtual: Amplify's
single parallax step). The bake makes one atlas per layout and size the variants name (methods share
it); vdmbake/kernels/octahedral.py holds the kernels."""
from __future__ import annotations

import time
from dataclasses import dataclass

from ..kernels import octahedral
from ..bundle import parts
from ..schema import Invalid, ListOf, Number, Parsed, Technique, setting

UP = (0.0, 0.0, 1.0)   # the hemisphere's up and the full map's centre view: world +Z


@dataclass(frozen=True)
class Variant:
    layout: str       # "full" (octahedral map of the sphere) or "hemi" (hemi-octahedral, above UP)
    views: int        # N: views per side of the map
    resolution: int   # R: texels per side of every view
    method: str       # "march" or "virtual"

    def __str__(self) -> str:
        return f"{self.atlas}-{self.method}"

    @property
    def atlas(self) -> str:
        """The atlas this variant draws (shared by the methods): LAYOUT-NxR."""
        return f"{self.layout}-{self.views}x{self.resolution}"


def _variant(m) -> Variant:
    v = Variant(m[1], int(m[2]), int(m[3]), m[4])
    if not (2 <= v.views <= 64 and octahedral.MIN_RESOLUTION <= v.resolution <= 4096
            and v.views * v.resolution <= octahedral.MAX_ATLAS):
        raise Invalid
    return v


# N and R of at most 5 digits: a longer number is out of range, and int() refuses one of more than 4300
VARIANT = Parsed(r"(full|hemi)-([0-9]{1,5})x([0-9]{1,5})-(march|virtual)", _variant,
                 "LAYOUT-NxR-METHOD: 'full-' or 'hemi-', then NxR (views per side N in [2, 64], texels per view "
                 f"R in [{octahedral.MIN_RESOLUTION}, 4096], N R <= {octahedral.MAX_ATLAS}), then '-march' or '-virtual'")


@dataclass(frozen=True)
class Options:
    variants: tuple[Variant, ...] = setting((VARIANT.parse("full-9x128-march"),), ListOf(VARIANT),
                                            "views, texels per view and search of each variant", knob="variant")
    shadow_scale: float = setting(2.0, Number(0.25, 64.0),
                                  "shadow-map texels per view texel (at most render.shadow_map)")


def bake(job) -> dict:
    """One atlas per LAYOUT-NxR the variants name: per view the normal's octahedral code in its frame,
    depth along the view and coverage, extrapolated around the silhouettes (vdmbake.bundle.parts.OCTAHEDRAL)."""
    out = {}
    for v in job.options.variants:
        if v.atlas in out:
            continue
        t0 = time.perf_counter()
        settings = octahedral.Settings(v.views, v.resolution, v.layout == "hemi")
        part = octahedral.to_part(octahedral.bake(job.mesh, settings, UP,
                                                  log=lambda m, key=v.atlas: job.log(f"octahedral {key}: {m}")))
        job.steps[f"octahedral_{v.atlas}_s"] = round(time.perf_counter() - t0, 3)
        out[v.atlas] = job.write(f"octahedral-{v.atlas}", parts.OCTAHEDRAL, part)   # the bare atlas freed first
        job.log(f"octahedral {v.atlas}: atlas {v.views * v.resolution}^2, "
                f"{job.writer.parts[out[v.atlas]]['bytes'] / 2**20:.2f} MB")
    return out


TECHNIQUE = Technique("octahedral", "octahedral impostors: one quad over the bounding sphere, per pixel the three "
                      "nearest of N x N baked views searched along the ray and blended, exact depth",
                      ("surface",), Options, bake=bake,
                      reads=lambda entry, variant, obj: {entry[variant.atlas]: parts.OCTAHEDRAL})
