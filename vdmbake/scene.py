"""Scene files (TOML): parsing, defaults and validation.

A scene names the objects to bake (a mesh file or a built-in primitive), the cameras,
one directional light plus ambient, the material constants of the shared shading model,
and per object the techniques to render and compare with their quality knobs.
Every error names the file, the key, the bad value and what is allowed.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import asdict, dataclass
from typing import Callable
from pathlib import Path

from .errors import InputError
from .heightfields import PATTERNS, SKIMAGE_PHOTOS
from .molecules import STYLES

MAX_SIDE = 8192  # largest accepted image side; the memory guard in vdmrender checks the rest



def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass(frozen=True)
class Knob:
    """A technique's quality knob: the list-valued option swept into an error-against-time curve."""
    key: str           # option name in the scene, e.g. "ratios"
    label: str         # one value's name in reports, e.g. "ratio"
    default: tuple
    check: Callable[[object], bool]
    allowed: str       # what check accepts, for error messages


@dataclass(frozen=True)
class TechniqueSpec:
    kinds: tuple[str, ...]                 # object kinds it draws: "surface" (mesh, primitive), "quadrics"
    knob: Knob | None = None
    options: tuple[tuple[str, float, float, float], ...] = ()   # scalar options: (name, default, lo, hi)
    mesostructure: bool = False            # draws the object's [objects.mesostructure] (which it then needs)


def _int_in(lo: int, hi: int) -> Callable[[object], bool]:
    return lambda x: isinstance(x, int) and not isinstance(x, bool) and lo <= x <= hi


TECHNIQUES: dict[str, TechniqueSpec] = {
    # the full mesh, rasterised, shadow map
    "mesh": TechniqueSpec(("surface",)),
    # the mesh simplified by quadric collapses to these face ratios
    "coarse": TechniqueSpec(("surface",), Knob("ratios", "ratio", (0.5, 0.1, 0.01),
                                                lambda x: _is_number(x) and 0 < x <= 1, "numbers in (0, 1]")),
    # spheres and capped cylinders ray cast per pixel (Sigg et al. 2006): direct or deferred shading,
    # deferred with Sobel silhouette/crease outlines of these strengths
    "impostor": TechniqueSpec(("quadrics",), Knob("shading", "shading", ("direct", "deferred", "outlines"),
                                                   lambda x: x in ("direct", "deferred", "outlines"),
                                                   "'direct', 'deferred', 'outlines'"),
                              (("silhouette", 1.0, 0.0, 100.0), ("crease", 1.0, 0.0, 100.0))),
    # instanced tessellated spheres (icosphere subdivision level) and cylinders (4 * 2^level sides)
    "tessellated": TechniqueSpec(("quadrics",), Knob("levels", "level", (0, 1, 2, 3), _int_in(0, 6),
                                                      "integers in [0, 6]")),
    # view-dependent displacement mapping (Wang et al. 2003) reconstructed from k eigenfunctions of the
    # SVD; "all" keeps every one (the uncompressed table, up to float32 rounding)
    "vdm": TechniqueSpec(("surface",), Knob("k", "k", (1, 2, 4, 8), lambda x: x == "all" or _int_in(1, 256)(x),
                                            "integers in [1, 256] or 'all'"), mesostructure=True),
    # the base mesh with the mesostructure's normals only (Blinn 1978)
    "bump": TechniqueSpec(("surface",), mesostructure=True),
    # parallax occlusion mapping: a linear search of this many steps plus one secant step, and the same
    # search towards the light for shadows
    "pom": TechniqueSpec(("surface",), Knob("steps", "steps", (8, 16, 32), _int_in(2, 1024),
                                            "integers in [2, 1024]"), mesostructure=True),
    # conventional displacement mapping: the base mesh subdivided this many times (4^level faces per
    # face), displaced, rasterised
    "displaced": TechniqueSpec(("surface",), Knob("levels", "level", (1, 2, 3), _int_in(0, 8),
                                                  "integers in [0, 8]"), mesostructure=True),
    # enhanced billboards (Vichitvejpaisal 2005): PROJECTION-METHOD[+coarse]; projection greedy (sec. 3.2) or
    # axis (+-X, +-Y, +-Z); method hit0.01 / hit0.02 (the thesis's 100-step march with that hit range),
    # improved (footprint steps, refinement) or hier (exact, through a baked min/max pyramid per map; its
    # shadows cast by the coarse mesh); +coarse fills holes with the coarse mesh (sec. 3.4).
    # resolution: map side in texels; coarse_ratio: faces kept by the coarse mesh
    "billboards": TechniqueSpec(("surface",), Knob(
        "variants", "variant", ("greedy-hit0.01", "greedy-hit0.02", "greedy-improved", "greedy-hit0.01+coarse",
                                "greedy-improved+coarse"),
        lambda x: isinstance(x, str) and re.fullmatch(r"(greedy|axis)-(hit0\.01|hit0\.02|improved|hier)(\+coarse)?", x)
        is not None, "'greedy-' or 'axis-', then 'hit0.01', 'hit0.02', 'improved' or 'hier', optionally '+coarse'"),
        (("resolution", 512, 8, 4096), ("coarse_ratio", 0.1, 1e-4, 1.0))),
}

# Built-in primitives -> parameters with their defaults (all lengths in scene units).
PRIMITIVES: dict[str, dict[str, float]] = {
    "plane": {"size": 2.0, "segments": 8},
    "sphere": {"radius": 1.0, "segments": 96, "rings": 48},
    "cylinder": {"radius": 0.5, "height": 2.0, "segments": 96, "rings": 8, "caps": 1},
    "cone": {"radius": 0.6, "height": 1.5, "segments": 96, "rings": 8, "caps": 1},
    "torus": {"major": 1.0, "minor": 0.35, "segments": 128, "rings": 64},
    "vase": {"radius": 0.5, "height": 2.0, "segments": 96, "rings": 64},
}
_NAME = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


@dataclass(frozen=True)
class Material:
    albedo: tuple[float, float, float] = (0.8, 0.76, 0.7)   # linear RGB
    diffuse: float = 1.0
    specular: float = 0.25
    shininess: float = 48.0


@dataclass(frozen=True)
class Light:
    direction: tuple[float, float, float] = (0.45, -0.55, 0.7)  # towards the light (normalised on load)
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ambient: tuple[float, float, float] = (0.12, 0.12, 0.13)


@dataclass(frozen=True)
class Orbit:
    count: int = 4
    elevation_deg: float = 20.0
    azimuth_deg: float = 30.0     # azimuth of the first camera; the others follow evenly
    distance: float = 2.8         # in bounding-sphere radii of the object, from its centre
    fov_deg: float = 40.0         # vertical field of view


@dataclass(frozen=True)
class Pose:
    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    fov_deg: float = 40.0


@dataclass(frozen=True)
class Camera:
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    orbit: Orbit | None = Orbit()
    poses: tuple[Pose, ...] = ()


@dataclass(frozen=True)
class Render:
    resolution: tuple[int, int] = (512, 512)   # width, height
    background: tuple[float, float, float] = (0.02, 0.022, 0.03)  # linear RGB
    repeats: int = 5          # timed renders of each frame; the report gives their median
    warmup: int = 1           # untimed renders of each frame first
    shadow_map: int = 2048    # shadow-map side in texels for rasterised techniques (4096: +0.006 dLuv better, ~+40 ms on llvmpipe)


@dataclass(frozen=True)
class Transform:
    """Scale, then rotate about X, Y, Z (degrees), then translate."""
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rotate_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Mesostructure:
    """Detail geometry over a surface object's UVs (VDM, sec. 3): a height field tiled `tiling` times
    over the UV square, lying inward of the surface, `depth` deep in tile units (a tile spans 1 x 1);
    the VDM tables sample it `size`^2 texels x `phi` x `theta` views x `curvatures`."""
    height: str                                  # a pattern (PATTERNS), skimage:NAME, or a PNG/EXR path
    size: int = 128
    depth: float = 0.05
    tiling: tuple[float, float] = (1.0, 1.0)
    phi: int = 32
    theta: int = 8
    curvatures: int = 16


@dataclass(frozen=True)
class Object:
    name: str
    mesh: str | None                 # a file trimesh reads, relative to the scene, or pkg:PACKAGE/PATH
    primitive: str | None
    params: dict                      # primitive parameters, defaults filled in
    molecule: str | None              # a PDB or mmCIF file (same path rules as mesh)
    style: str | None                 # molecule style, one of STYLES
    spheres: tuple                    # inline spheres (x, y, z, radius)
    cylinders: tuple                  # inline capped cylinders (x0, y0, z0, x1, y1, z1, radius)
    transform: Transform
    material: Material
    techniques: dict                  # technique -> options, defaults filled in, in scene order
    mesostructure: Mesostructure | None = None

    @property
    def kind(self) -> str:
        return _kind(self.mesh, self.primitive)


@dataclass(frozen=True)
class Scene:
    render: Render
    camera: Camera
    light: Light
    objects: tuple[Object, ...]

    def to_dict(self) -> dict:
        """The resolved scene (every default filled in) as plain data; parse_scene_dict reads it back."""
        return {
            "render": asdict(self.render),
            "camera": {k: v for k, v in asdict(self.camera).items() if v is not None},
            "light": asdict(self.light),
            "objects": [{k: v for k, v in asdict(o).items() if v is not None and v != () and v != {}}
                        for o in self.objects],
        }


class _Table:
    """A TOML table being read: checks types and ranges, and rejects keys nobody read."""

    def __init__(self, data, where: str, origin: str):
        if not isinstance(data, dict):
            raise InputError(f"{origin}: [{where}] must be a table, got {data!r}.")
        self.data, self.where, self.origin, self.used = data, where, origin, set()

    def _fail(self, key, value, allowed):
        raise InputError(f"{self.origin}: key '{self.key(key)}' has value {value!r}; allowed: {allowed}.")

    def key(self, key):
        return f"{self.where}.{key}" if self.where else key

    def has(self, key):
        return self.data.get(key) is not None   # JSON null (a manifest's "no value") counts as absent

    def raw(self, key, default=None):
        self.used.add(key)
        return self.data.get(key, default)

    def number(self, key, default, lo=-math.inf, hi=math.inf, integer=False):
        v = self.raw(key, default)
        kind = "an integer" if integer else "a number"
        ok = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok or not math.isfinite(v) or not lo <= v <= hi:
            self._fail(key, v, f"{kind} in [{lo}, {hi}]")
        return int(v) if integer else float(v)

    def vector(self, key, default, n=3, lo=-math.inf, hi=math.inf, nonzero=False):
        v = self.raw(key, default)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and n == 3 and key == "scale":
            v = [v, v, v]
        good = (isinstance(v, (list, tuple)) and len(v) == n and all(
            _is_number(x) and lo <= x <= hi
            for x in v))
        if not good or (nonzero and not any(v)):
            self._fail(key, v, f"a list of {n} finite numbers in [{lo}, {hi}]" + (", not all zero" if nonzero else ""))
        return tuple(float(x) for x in v)

    def choice(self, key, default, allowed):
        v = self.raw(key, default)
        if v not in allowed:
            self._fail(key, v, ", ".join(repr(a) for a in allowed))
        return v

    def table(self, key):
        return _Table(self.raw(key, {}), self.key(key), self.origin)

    def done(self):
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            allowed = ", ".join(sorted(self.used)) or "none"
            raise InputError(f"{self.origin}: unknown key '{self.key(unknown[0])}' in [{self.where or 'top level'}]; "
                             f"allowed keys there: {allowed}.")


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: scene file not found.") from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot read the scene file ({e}).") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: malformed TOML: {e}.") from None
    return parse_scene_dict(data, str(path))


def parse_scene_dict(data: dict, origin: str) -> Scene:
    """Validate a scene given as plain data (from TOML, or from a bundle's manifest)."""
    top = _Table(data, "", origin)
    render = _render(top.table("render"))
    camera = _camera(top.table("camera"))
    light = _light(top.table("light"))
    default_material = _material(top.table("material"), Material())
    objects = top.raw("objects")
    if not isinstance(objects, list) or not objects:
        raise InputError(f"{origin}: the scene needs at least one [[objects]] entry "
                         "(with 'mesh = PATH' or 'primitive = NAME').")
    objs = tuple(_object(_Table(o, f"objects[{i}]", origin), default_material) for i, o in enumerate(objects))
    names = [o.name for o in objs]
    for n in names:
        if names.count(n) > 1:
            raise InputError(f"{origin}: two objects are named {n!r}; object names must be unique.")
    top.done()
    return Scene(render, camera, light, objs)


def _render(t: _Table) -> Render:
    d = Render()
    res = t.raw("resolution", list(d.resolution))
    if not (isinstance(res, (list, tuple)) and len(res) == 2
            and all(isinstance(x, int) and not isinstance(x, bool) and 1 <= x <= MAX_SIDE for x in res)):
        t._fail("resolution", res, f"[width, height], integers in [1, {MAX_SIDE}]")
    r = Render(
        resolution=(int(res[0]), int(res[1])),
        background=t.vector("background", d.background, lo=0.0, hi=1.0),
        repeats=t.number("repeats", d.repeats, 1, 1000, integer=True),
        warmup=t.number("warmup", d.warmup, 0, 100, integer=True),
        shadow_map=t.number("shadow_map", d.shadow_map, 256, 16384, integer=True),
    )
    t.done()
    return r


def _camera(t: _Table) -> Camera:
    up = t.vector("up", Camera.up, nonzero=True)
    poses = t.raw("poses", [])
    if not isinstance(poses, list):
        t._fail("poses", poses, "an array of tables [[camera.poses]] with eye, target, fov_deg")
    orbit = None
    if not poses or t.has("orbit"):
        o, d = t.table("orbit"), Orbit()
        orbit = Orbit(
            count=o.number("count", d.count, 1, 360, integer=True),
            elevation_deg=o.number("elevation_deg", d.elevation_deg, -89.0, 89.0),
            azimuth_deg=o.number("azimuth_deg", d.azimuth_deg, -360.0, 360.0),
            distance=o.number("distance", d.distance, 1e-3, 1e4),
            fov_deg=o.number("fov_deg", d.fov_deg, 1.0, 175.0),
        )
        o.done()
    parsed = []
    for i, p in enumerate(poses):
        pt = _Table(p, f"camera.poses[{i}]", t.origin)
        pose = Pose(eye=pt.vector("eye", None), target=pt.vector("target", None),
                    fov_deg=pt.number("fov_deg", 40.0, 1.0, 175.0))
        if pose.eye == pose.target:
            pt._fail("target", list(pose.target), "a point different from eye")
        pt.done()
        parsed.append(pose)
    t.done()
    return Camera(up=up, orbit=orbit, poses=tuple(parsed))


def _light(t: _Table) -> Light:
    d = Light()
    direction = t.vector("direction", d.direction, nonzero=True)
    n = math.sqrt(sum(x * x for x in direction))
    light = Light(direction=tuple(x / n for x in direction),
                  color=t.vector("color", d.color, lo=0.0, hi=1e3),
                  ambient=t.vector("ambient", d.ambient, lo=0.0, hi=1e3))
    t.done()
    return light


def _material(t: _Table, d: Material) -> Material:
    m = Material(albedo=t.vector("albedo", d.albedo, lo=0.0, hi=1.0),
                 diffuse=t.number("diffuse", d.diffuse, 0.0, 10.0),
                 specular=t.number("specular", d.specular, 0.0, 10.0),
                 shininess=t.number("shininess", d.shininess, 1.0, 1e4))
    t.done()
    return m


def _object(t: _Table, default_material: Material) -> Object:
    name = t.raw("name")
    if not isinstance(name, str) or not _NAME.match(name):
        t._fail("name", name, "1-64 characters from A-Z a-z 0-9 _ -")
    sources = [k for k in ("mesh", "primitive", "molecule") if t.has(k)] + (
        ["spheres/cylinders"] if t.has("spheres") or t.has("cylinders") else [])
    if len(sources) != 1:
        raise InputError(f"{t.origin}: [{t.where}] (object {name!r}) needs exactly one source: 'mesh = PATH', "
                         f"'primitive = NAME' (NAME one of {', '.join(PRIMITIVES)}), 'molecule = PATH' "
                         f"(PDB or mmCIF), or inline 'spheres'/'cylinders' lists; it has "
                         f"{', '.join(sources) or 'none'}.")
    mesh, primitive, molecule = (_path(t, k) for k in ("mesh", "primitive", "molecule"))
    params = {}
    if primitive is not None:
        primitive = t.choice("primitive", None, list(PRIMITIVES))
        pt = t.table("params")
        for k, default in PRIMITIVES[primitive].items():
            integer = isinstance(default, int)
            lo = (0 if k == "caps" else 1) if integer else 1e-9
            params[k] = pt.number(k, default, lo, 4096 if integer else 1e9, integer=integer)
        pt.done()
    elif t.raw("params"):
        t._fail("params", t.data["params"], "no params here (they belong to primitives)")
    if molecule is None and t.has("style"):
        t._fail("style", t.data["style"], "a style only for molecule objects")
    style = t.choice("style", STYLES[0], STYLES) if molecule is not None else None
    spheres = _rows(t, "spheres", 4, "[x, y, z, radius]")
    cylinders = _rows(t, "cylinders", 7, "[x0, y0, z0, x1, y1, z1, radius]")
    tr = t.table("transform")
    transform = Transform(tr.vector("scale", Transform.scale, lo=1e-9, hi=1e9),
                          tr.vector("rotate_deg", Transform.rotate_deg),
                          tr.vector("translate", Transform.translate))
    tr.done()
    material = _material(t.table("material"), default_material)
    meso = _mesostructure(t) if t.has("mesostructure") else None
    if meso and not (mesh or primitive):
        t._fail("mesostructure", t.data["mesostructure"], "a mesostructure only on mesh or primitive objects")
    techniques = _techniques(t.table("techniques"), name, _kind(mesh, primitive), meso is not None)
    t.done()
    return Object(name, mesh, primitive, params, molecule, style, spheres, cylinders, transform, material,
                  techniques, meso)


def _mesostructure(parent: _Table) -> Mesostructure:
    t, d = parent.table("mesostructure"), Mesostructure("")
    height = t.raw("height")
    if not isinstance(height, str) or not height:
        t._fail("height", height, f"a pattern ({', '.join(PATTERNS)}), skimage:NAME ({', '.join(SKIMAGE_PHOTOS)}) "
                "or a PNG/EXR path (relative to the scene, or pkg:PACKAGE/PATH)")
    m = Mesostructure(height=height,
                      size=t.number("size", d.size, 4, 1024, integer=True),
                      depth=t.number("depth", d.depth, 0.0, 1.0),
                      tiling=t.vector("tiling", d.tiling, n=2, lo=1e-3, hi=1e4),
                      phi=t.number("phi", d.phi, 1, 256, integer=True),
                      theta=t.number("theta", d.theta, 1, 64, integer=True),
                      curvatures=t.number("curvatures", d.curvatures, 1, 64, integer=True))
    t.done()
    return m


def _kind(mesh, primitive) -> str:
    """Surfaces (a mesh file or a primitive) and quadrics (molecules, inline spheres/cylinders)
    are drawn by different techniques."""
    return "surface" if (mesh or primitive) else "quadrics"


def _path(t: _Table, key: str) -> str | None:
    v = t.raw(key)
    if v is not None and (not isinstance(v, str) or not v):
        t._fail(key, v, "a file path (relative to the scene) or pkg:PACKAGE/PATH" if key != "primitive"
                else ", ".join(PRIMITIVES))
    return v


def _rows(t: _Table, key: str, n: int, shape: str) -> tuple:
    """An inline list of quadrics: rows of n finite numbers, the last (a radius) >= 0."""
    rows = t.raw(key, [])
    good = isinstance(rows, list) and all(
        isinstance(r, list) and len(r) == n and all(_is_number(x) for x in r) and r[-1] >= 0 for r in rows)
    if not good:
        t._fail(key, rows if len(str(rows)) < 200 else f"{str(rows)[:200]}...",
                f"a list of {shape} rows of finite numbers, radius >= 0")
    return tuple(tuple(float(x) for x in r) for r in rows)


def _techniques(t: _Table, name: str, kind: str, has_meso: bool) -> dict:
    fitting = [k for k, spec in TECHNIQUES.items() if kind in spec.kinds]
    if not t.data:
        raise InputError(f"{t.origin}: object {name!r} has no [{t.where}]; name at least one of "
                         f"{', '.join(fitting)}, e.g. techniques = {{ {fitting[0]} = {{}} }}.")
    out = {}
    for tech in list(t.data):
        if tech not in TECHNIQUES:
            raise InputError(f"{t.origin}: unknown technique '{tech}' in [{t.where}]; "
                             f"known techniques: {', '.join(TECHNIQUES)}.")
        spec = TECHNIQUES[tech]
        if kind not in spec.kinds:
            raise InputError(f"{t.origin}: technique '{tech}' in [{t.where}] does not draw {kind} objects "
                             f"like {name!r}; techniques for them: {', '.join(fitting)}.")
        if spec.mesostructure and not has_meso:
            raise InputError(f"{t.origin}: technique '{tech}' in [{t.where}] draws a mesostructure, but object "
                             f"{name!r} has none; add [objects.mesostructure] with height = PATTERN or PATH "
                             f"(patterns: {', '.join(PATTERNS)}).")
        opts = t.table(tech)
        out[tech] = {}
        if spec.knob:
            k = spec.knob
            v = opts.raw(k.key, list(k.default))
            if not isinstance(v, list) or not v or len(set(map(str, v))) != len(v) or not all(map(k.check, v)):
                opts._fail(k.key, v, f"a non-empty list of distinct values, each one of: {k.allowed}")
            out[tech][k.key] = [float(x) if isinstance(x, float) else x for x in v]
        for opt, default, lo, hi in spec.options:
            out[tech][opt] = opts.number(opt, default, lo, hi)
        opts.done()
    return out
