"""Technique `coarse`: the mesh simplified by quadric error collapses (fast-simplification), one
variant per ratio of faces kept."""
from __future__ import annotations

from dataclasses import dataclass

from ..kernels import coarse
from ..bundle import parts
from ..errors import InputError
from ..schema import ListOf, Number, Technique, setting


@dataclass(frozen=True)
class Options:
    ratios: tuple[float, ...] = setting((0.5, 0.1, 0.01), ListOf(Number(0.0, 1.0, open_lo=True)),
                                        "faces kept, as a fraction of the full mesh's", knob="ratio")


def bake(job) -> dict:
    meshes = []
    for ratio in job.options.ratios:
        c = coarse.simplify(job.mesh, ratio)
        if not len(c.faces):
            raise InputError(f"object {job.obj.name!r}: techniques.coarse.ratios value {ratio:g} leaves no face of "
                             f"the {len(job.mesh.faces)}; choose a larger ratio.")
        meshes.append({"ratio": ratio, "mesh": job.write(f"coarse-{ratio:g}", parts.MESH, c)})
        job.log(f"coarse {ratio:g} -> {len(c.faces)} faces")
    return {"meshes": meshes}


def reads(entry: dict, ratio: float, obj) -> dict:
    return {next(m["mesh"] for m in entry["meshes"] if m["ratio"] == ratio): parts.MESH}


TECHNIQUE = Technique("coarse", "the mesh simplified by fast-simplification (quadric collapses)", ("surface",),
                      Options, bake=bake, reads=reads)
