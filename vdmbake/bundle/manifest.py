"""The manifest's schema (docs/bundle.md), checked before anything else of a bundle is read: its
types and required keys as dataclasses of the scene's typed settings (vdmbake.schema), each part
kind's metadata by the kind's own schema (vdmbake.bundle.parts), and the cross-references: the scene's
objects are the manifest's, every part an object or a technique variant reads is listed with the
kind expected, finite centres and positive radii. Each error names the manifest and the key."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..errors import InputError, escaped
from .parts import KINDS
from .parts.kind import check_extent
from ..schema import REQUIRED, Choice, Custom, Integer, Number, Reader, Text, Vector, read, setting

_PATH = Text("a part path listed in 'parts'")
_DIGEST = Text("64 lowercase hexadecimal digits", r"[0-9a-f]{64}")


@dataclass(frozen=True, kw_only=True)
class PartEntry:
    kind: str = setting(REQUIRED, Choice(*KINDS), "the part's kind")
    sha256: str = setting(REQUIRED, _DIGEST, "checksum of its bytes")
    bytes: int = setting(REQUIRED, Integer(0, 2**53), "its size")


@dataclass(frozen=True, kw_only=True)
class ObjectEntry:
    kind: str = setting(REQUIRED, Choice("surface", "quadrics"), "what draws it")
    centre: tuple = setting(REQUIRED, Vector(3), "bounding sphere centre")            # in range: check_extent
    radius: float = setting(REQUIRED, Number(0.0, open_lo=True), "bounding sphere radius")
    mesh: str | None = setting(None, _PATH, "surfaces: the full mesh")
    quadrics: str | None = setting(None, _PATH, "quadrics: the spheres and cylinders")
    mesostructure: str | None = setting(None, _PATH, "the height field and normal map")
    viewer_mesh: str | None = setting(None, _PATH, "quadrics: the optional triangle mesh for viewers")
    albedo_map: str | None = setting(None, _PATH, "surfaces: the asset's base-colour texture, if it has one")
    mesostructure_albedo: str | None = setting(None, _PATH, "the mesostructure's colour tile, if the scene gives one")
    spheres_dropped: int = setting(0, Integer(0, 2**53), "spheres without volume left out")
    cylinders_dropped: int = setting(0, Integer(0, 2**53), "cylinders without volume left out")
    techniques: dict = setting(REQUIRED, Custom("a table of technique entries"), "each baking technique's parts")


# The kind of part each path of an object entry names.
_PATH_KINDS = {"mesh": "mesh", "quadrics": "quadrics", "mesostructure": "mesostructure", "viewer_mesh": "viewer-mesh",
               "albedo_map": "albedo-map", "mesostructure_albedo": "albedo-map"}


@dataclass(frozen=True, kw_only=True)
class Top:
    tool_version: str = setting(REQUIRED, Text(), "vdmbake's version")
    scene: dict = setting(REQUIRED, Custom("the resolved scene"), "the scene, every default filled in")
    objects: dict = setting(REQUIRED, Custom("a table of object entries"), "per object")
    parts: dict = setting(REQUIRED, Custom("a table of part entries"), "per part path")


def _typed(cls, data, where: str, origin: str):
    """`read` of the keys `cls` declares; keys it does not know are left to newer readers."""
    if not isinstance(data, dict):
        raise InputError(f"{origin}: key '{where}' has value of type {type(data).__name__}; allowed: a table.")
    names = {f.name for f in dataclasses.fields(cls)}
    return read(cls, Reader({k: v for k, v in data.items() if k in names}, where, origin))


def _table(t: Reader, key: str) -> dict:
    value = t.data[key]
    if not isinstance(value, dict):
        t.fail(key, value, "a table")
    return value


def check_meta(kind, meta: dict, rel: str, origin: str) -> None:
    """A part kind's manifest metadata checked by the kind's schema."""
    _typed(kind.meta, meta, f"parts.{escaped(rel)}", origin)


def validate(manifest, origin: str):
    """The scene (vdmbake.scene.Scene) of a manifest whose format and version were checked, after
    checking everything the renderer reads from it; raises InputError naming the key."""
    from ..scene import REGISTRY, parse_scene_dict   # the scene module imports the techniques

    top = Reader(manifest, "", origin)
    _typed(Top, manifest, "", origin)
    parts = _table(top, "parts")
    for rel, meta in parts.items():
        entry = _typed(PartEntry, meta, f"parts.{escaped(rel)}", origin)
        check_meta(KINDS[entry.kind], meta, rel, origin)
    objects = _table(top, "objects")
    scene = parse_scene_dict(manifest["scene"], f"{origin} (scene)")
    if set(objects) != {o.name for o in scene.objects}:
        raise InputError(f"{origin}: key 'objects' lists {sorted(objects)} but the scene has objects "
                         f"{sorted(o.name for o in scene.objects)}; re-bake with vdmbake --force.")

    def part(key: str, rel, kind) -> None:
        meta = parts.get(rel) if isinstance(rel, str) else None
        if meta is None or meta["kind"] != kind.name:
            raise InputError(f"{origin}: key '{key}' names {rel!r}, which 'parts' does not list as a "
                             f"{kind.name!r} part; re-bake with vdmbake --force.")

    for obj in scene.objects:
        where = f"objects.{obj.name}"
        e = _typed(ObjectEntry, objects[obj.name], where, origin)
        if not isinstance(e.techniques, dict):
            Reader({}, where, origin).fail("techniques", e.techniques, "a table of technique entries")
        if e.kind != obj.kind:
            Reader({}, where, origin).fail("kind", e.kind, repr(obj.kind) + " (the scene's object)")
        check_extent(f"{origin}: key '{where}'", e.centre, e.radius)
        if obj.instances is not None:    # every copy as the object itself (what the reference holds)
            from ..common import instances
            instances.check(instances.matrices(obj.instances, scene.camera.up, e.centre), e.centre, e.radius,
                            f"{origin}: key '{where}'")
        for key, kind in _PATH_KINDS.items():      # every part the entry names, whether the object reads it or not
            if getattr(e, key) is not None:
                part(f"{where}.{key}", getattr(e, key), KINDS[kind])
        part(f"{where}.{'mesh' if obj.kind == 'surface' else 'quadrics'}",
             e.mesh if obj.kind == "surface" else e.quadrics, KINDS["mesh" if obj.kind == "surface" else "quadrics"])
        if obj.viewer_mesh is not None:
            part(f"{where}.viewer_mesh", e.viewer_mesh, KINDS["viewer-mesh"])
        if obj.mesostructure:
            part(f"{where}.mesostructure", e.mesostructure, KINDS["mesostructure"])
            if parts[e.mesostructure]["size"] != obj.mesostructure.size:
                raise InputError(f"{origin}: part {e.mesostructure!r} has size {parts[e.mesostructure]['size']} "
                                 f"but the scene's mesostructure size is {obj.mesostructure.size}; re-bake.")
            if (e.mesostructure_albedo is None) != (obj.mesostructure.albedo is None):
                raise InputError(f"{origin}: key '{where}.mesostructure_albedo' is "
                                 f"{'missing' if e.mesostructure_albedo is None else 'present'} but the scene's "
                                 f"mesostructure has {'an' if obj.mesostructure.albedo else 'no'} albedo; re-bake.")
        for name, options in obj.techniques.items():
            t = REGISTRY[name]
            if t.reads is None:
                continue
            key = f"{where}.techniques.{name}"
            tech = e.techniques.get(name)
            for value in t.values(options):
                try:
                    needed = t.reads(tech, value, obj)
                except (KeyError, TypeError, IndexError, ValueError, StopIteration, AttributeError):
                    raise InputError(f"{origin}: key '{key}' has no usable entry for variant {t.label(value)} "
                                     "(missing or malformed); re-bake with vdmbake --force.") from None
                for rel, kind in needed.items():
                    part(key, rel, kind)
                    for k, v in tech.items():        # what the entry and the part's metadata both record agrees
                        if k in parts[rel] and k not in PartEntry.__dataclass_fields__ and parts[rel][k] != v:
                            Reader({}, key, origin).fail(k, v, f"{parts[rel][k]!r}, as part {rel!r} records; re-bake")
    return scene
