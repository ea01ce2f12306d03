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
from pathlib import Path

from .errors import InputError

MAX_SIDE = 8192  # largest accepted image side; the memory guard in vdmrender checks the rest

# Technique name -> its options with their defaults. A technique's "knob" (the option
# swept into an error-against-time curve) is the list-valued option, if any.
TECHNIQUES: dict[str, dict[str, object]] = {
    "mesh": {},                                   # the full mesh, rasterised (shadow map)
    "coarse": {"ratios": [0.5, 0.1, 0.01]},       # the mesh simplified to these face ratios
}
KNOBS = {"coarse": "ratios"}

# Built-in primitives -> parameters with their defaults (all lengths in scene units).
PRIMITIVES: dict[str, dict[str, float]] = {
    "plane": {"size": 2.0, "segments": 8},
    "sphere": {"radius": 1.0, "segments": 96, "rings": 48},
    "cylinder": {"radius": 0.5, "height": 2.0, "segments": 96, "rings": 8, "caps": 1},
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
class Object:
    name: str
    mesh: str | None                 # a file trimesh reads, relative to the scene, or pkg:PACKAGE/PATH
    primitive: str | None
    params: dict                      # primitive parameters, defaults filled in
    transform: Transform
    material: Material
    techniques: dict                  # technique -> options, defaults filled in, in scene order


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
            "camera": asdict(self.camera),
            "light": asdict(self.light),
            "objects": [asdict(o) for o in self.objects],
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
        return key in self.data

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
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and lo <= x <= hi
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
    mesh, primitive = t.raw("mesh"), t.raw("primitive")
    if (mesh is None) == (primitive is None):
        raise InputError(f"{t.origin}: [{t.where}] (object {name!r}) needs exactly one of "
                         f"'mesh = PATH' or 'primitive = NAME' (NAME one of {', '.join(PRIMITIVES)}).")
    params = {}
    if mesh is not None:
        if not isinstance(mesh, str) or not mesh:
            t._fail("mesh", mesh, "a file path (relative to the scene) or pkg:PACKAGE/PATH")
        if t.raw("params"):
            t._fail("params", t.data["params"], "no params for a mesh file (they belong to primitives)")
    else:
        primitive = t.choice("primitive", None, list(PRIMITIVES))
        pt = t.table("params")
        for k, default in PRIMITIVES[primitive].items():
            integer = isinstance(default, int)
            lo = (0 if k == "caps" else 1) if integer else 1e-9
            params[k] = pt.number(k, default, lo, 4096 if integer else 1e9, integer=integer)
        pt.done()
    tr = t.table("transform")
    transform = Transform(tr.vector("scale", Transform.scale, lo=1e-9, hi=1e9),
                          tr.vector("rotate_deg", Transform.rotate_deg),
                          tr.vector("translate", Transform.translate))
    tr.done()
    material = _material(t.table("material"), default_material)
    techniques = _techniques(t.table("techniques"), name)
    t.done()
    return Object(name, mesh, primitive, params, transform, material, techniques)


def _techniques(t: _Table, name: str) -> dict:
    if not t.data:
        raise InputError(f"{t.origin}: object {name!r} has no [{t.where}]; name at least one of "
                         f"{', '.join(TECHNIQUES)}, e.g. techniques = {{ mesh = {{}} }}.")
    out = {}
    for tech in list(t.data):
        if tech not in TECHNIQUES:
            raise InputError(f"{t.origin}: unknown technique '{tech}' in [{t.where}]; "
                             f"known techniques: {', '.join(TECHNIQUES)}.")
        opts = t.table(tech)
        out[tech] = {}
        for k, default in TECHNIQUES[tech].items():
            if isinstance(default, list):
                v = opts.raw(k, default)
                if (not isinstance(v, list) or not v or len(set(v)) != len(v) or not all(
                        isinstance(x, (int, float)) and not isinstance(x, bool) and 0 < x <= 1 for x in v)):
                    opts._fail(k, v, "a non-empty list of distinct numbers in (0, 1]")
                out[tech][k] = [float(x) for x in v]
            else:
                out[tech][k] = opts.number(k, default)
        opts.done()
    return out
