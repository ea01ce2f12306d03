"""Technique `coarse`: the mesh simplified by quadric error collapses (fast-simplification), one
variant per ratio of faces kept."""
from __future__ import annotations

from dataclasses import dataclass

from ..kernels import coarse
from ..bundle import parts
from ..errors import InputError
from ..schema import ListOf, Number, Technique, setting, shortest


@dataclass(frozen=True)
class Options:
    ratios: tuple[float, ...] = setting((0.5, 0.1, 0.01), ListOf(Number(0.0, 1.0, open_lo=True)),
                                        "faces kept, as a fraction of the full mesh's", knob="ratio")


def simplified(job, ratio: float, key: str):
    """The job's mesh simplified to `ratio` of its faces (coarse.simplify), refused when nothing is left (`key`:
    the scene setting that asked for it)."""
    c = coarse.simplify(job.mesh, ratio)
    if not len(c.faces):
        raise InputError(f"object {job.obj.name!r}: {key} value {ratio:g} leaves no face of the "
                         f"{len(job.mesh.faces)} (faces narrower than a billionth of the mesh's size collapse first); "
                         "choose a larger ratio or a mesh with larger faces.")
    return c


def bake(job) -> dict:
    meshes = []
    for ratio in job.options.ratios:
        c = simplified(job, ratio, "techniques.coarse.ratios")
        meshes.append({"ratio": ratio, "mesh": job.write(f"coarse-{shortest(ratio)}", parts.MESH, c)})
        job.log(f"coarse {ratio:g} -> {len(c.faces)} faces")
    return {"meshes": meshes}


def reads(entry: dict, ratio: float, obj) -> dict:
    return {next(m["mesh"] for m in entry["meshes"] if m["ratio"] == ratio): parts.MESH}


TECHNIQUE = Technique("coarse", "the mesh simplified by fast-simplification (quadric collapses)", ("surface",),
                      Options, bake=bake, reads=reads, triangles="mesh")
