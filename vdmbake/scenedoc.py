"""The scene reference in docs/scenes.md, generated from the scene's dataclasses and the technique
registry (vdmbake.schema), so that it cannot drift from the code. `python -m vdmbake.scenedoc
docs/scenes.md` rewrites the block between the markers; a test checks that the block is current.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .assets.primitives import PRIMITIVES
from .schema import knob, markdown, settings
from .scene import (Cameras, Light, Material, Mesostructure, Object, Orbit, Placement, Pose, Render, Scatter,
                    Sweep, Thresholds, Transform)
from .techniques import REGISTRY

BEGIN = "<!-- scene reference: generated from the code by `python -m vdmbake.scenedoc docs/scenes.md` -->"
END = "<!-- end of the generated scene reference -->"
HEAD = ["| key | allowed | default | meaning |", "|---|---|---|---|"]


def _table(title: str, rows: list[str], note: str = "") -> list[str]:
    return [f"#### {title}", ""] + ([note, ""] if note else []) + HEAD + rows + [""]


def reference() -> str:
    """The markdown of every scene key, primitive parameter and technique setting."""
    out = _table("`[render]`", markdown(Render))
    out += _table("`[render.sweep]`", markdown(Sweep)[:1] + markdown(Thresholds, "lod[]."),
                  "Every view again with the object at each size on screen (vdmrender.views.sweep), and per "
                  "`[[render.sweep.lod]]` a LOD chain: per band of sizes the cheapest variant within its limits "
                  "(`lod.json`; vdmrender.deciding.lod).")
    out += _table("`[camera]`", markdown(Cameras)[:1] + markdown(Orbit, "orbit.") + markdown(Pose, "poses[]."),
                  "Without `poses`, or with an `orbit` table beside them, each object gets the orbit cameras, "
                  "framed on its bounding sphere; `[[camera.poses]]` add cameras at absolute positions.")
    out += _table("`[light]`", markdown(Light))
    out += _table("`[material]`", markdown(Material), "The shared shading model's constants; an object's "
                  "`material` table overrides some of them for that object.")
    plain = [f for f in settings(Object) if f.name not in ("transform", "material", "mesostructure")]
    rows = [r for f, r in zip(settings(Object), markdown(Object)) if f in plain]
    out += _table("`[[objects]]`", rows + markdown(Transform, "transform.") + markdown(Material, "material."))
    for name, (_, params) in PRIMITIVES.items():
        out += _table(f"`params` of `primitive = \"{name}\"`", markdown(params))
    out += _table("`[objects.instances]`", markdown(Placement, "placements[].") + markdown(Scatter, "scatter."),
                  "The object drawn many times from one bake, by instanced draws (vdmbake.common.instances): exactly "
                  "one of `placements` or `scatter`; every copy a uniform scale, a turn and a move about the object's "
                  "bounding-sphere centre. The cameras frame every copy, the shadow map spans them, and the "
                  "reference traces them all, merged (the memory guard counts each copy's faces). With "
                  "`[[render.sweep.lod]]`, the sweep draws one copy, and each chain adds a row `lod@CHAIN`: per frame "
                  "every copy drawn by the variant its screen size selects, as an engine would (vdmrender.views.lodmix.LodMix).")
    out += _table("`[objects.mesostructure]`", markdown(Mesostructure),
                  "Mesh or primitive objects with texture coordinates; needed by `vdm`, `pom`, `bump`, `displaced`.")
    out += ["#### Techniques (`[objects.techniques]`)", "",
            "Each technique is a table of its settings (`{}` for the defaults); the knob (a list) makes one "
            "variant per value, one point each on the error-against-time chart.", "",
            "| technique | objects | what it draws | knob |", "|---|---|---|---|"]
    for t in REGISTRY.values():
        k = knob(t.options)
        kinds = " and ".join({"surface": "mesh, primitive", "quadrics": "molecule, spheres/cylinders"}[x]
                             for x in t.kinds) + (" with a mesostructure" if t.mesostructure else "")
        out.append(f"| `{t.name}` | {kinds} | {t.summary} | {f'`{k.name}`' if k else 'none'} |")
    out.append("")
    for t in REGISTRY.values():
        if settings(t.options):
            out += _table(f"`{t.name}` settings", markdown(t.options, f"{t.name}."))
    return "\n".join(out).rstrip() + "\n"


def block() -> str:
    return f"{BEGIN}\n\n{reference()}\n{END}"


def update(readme: Path) -> bool:
    """Rewrite the generated block of `readme`; True if it changed."""
    text = readme.read_text()
    start, end = text.index(BEGIN), text.index(END) + len(END)
    new = text[:start] + block() + text[end:]
    readme.write_text(new)
    return new != text


if __name__ == "__main__":
    path = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/scenes.md")
    print(f"{path}: {'updated' if update(path) else 'already current'}")
