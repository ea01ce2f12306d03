"""Scene files (TOML): the settings of a bake and a render, typed, defaulted and validated.

A scene names the objects to bake (a mesh file, a built-in primitive, a molecule or inline
spheres and cylinders), the cameras, one directional light plus ambient, the material constants
of the shared shading model, and per object the techniques to render and compare with their
quality knobs. Each dataclass below is its own schema (vdmbake.schema): the scene reference (docs/scenes.md)
is generated from it, and every error names the file, the key, the bad value and what is allowed.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

from .errors import InputError, escaped
from .formats.safeio import read_regular
from .assets.heightfields import PATTERNS, SKIMAGE_PHOTOS
from .assets import meso_albedo
from .assets.molecules import STYLES
from .assets.primitives import PRIMITIVES
from .schema import (REQUIRED, Boolean, Choice, Custom, Direction, unit, Integer, Invalid, ListOf, Number, Reader,
                     Square, Table, Tables, Text, Type,
                     Vector, dump, read, setting)
from .techniques import REGISTRY

MAX_SCENE_BYTES = 64 << 20
TRIANGLE_MESHES = tuple(n for n, t in REGISTRY.items() if t.triangles == "mesh")   # what a glTF carries as it is
BY_FACES = tuple(n for n, t in REGISTRY.items() if t.triangles)                    # levels ranked by their faces
MAX_SIDE = 8192  # largest accepted image side; the memory guard in vdmrender checks the rest
MAX_SPP = 256    # the reference's samples per pixel, at most (16 x 16)
# The anti-aliasing modes (render.antialias) by name: (kind, n), msaaN N samples per pixel, ssaaK K x K pixels per pixel.
ANTIALIAS = {"none": ("none", 1), **{f"msaa{n}": ("msaa", n) for n in (2, 4, 8)},
             **{f"ssaa{k}": ("ssaa", k) for k in (2, 3, 4)}}


class VariantSets(Type):
    """Composite frames: a list of tables, each naming one variant label (as the report spells it) per
    object; the scene reader checks the names against the objects (check_composite)."""
    text = "a non-empty list of tables, each naming one variant per object by its report label"

    def parse(self, raw):
        if not isinstance(raw, list) or not raw or not all(
                isinstance(s, dict) and s and all(isinstance(v, str) for v in s.values()) for s in raw):
            raise Invalid
        return tuple(dict(s) for s in raw)

    def dump(self, value):
        return [dict(s) for s in value]


# What a LOD chain's limits bound (Thresholds.limit_on): each limit's report field, against the full asset or the
# reference (vdmrender.comparing.change).
LIMIT_ON = {"change": {"mean_dluv": "change_dluv", "p95_dluv": "change_p95_dluv", "flip": "change_flip",
                       "iou": "change_iou"},
            "reference": {"mean_dluv": "mean_dluv", "p95_dluv": "p95_dluv", "flip": "flip_mean", "iou": "iou"}}


@dataclass(frozen=True)
class Thresholds:
    """One LOD chain's limits (vdmrender.deciding.lod): a variant may be chosen at a screen size only if what the limits are
    on (`limit_on`) stays under every limit given there, over all the views together."""
    name: str = setting(REQUIRED, Text("1-64 characters from A-Z a-z 0-9 _ -", r"[A-Za-z0-9_-]{1,64}"),
                        "the chain's name (lod.json, the report)")
    mean_dluv: float | None = setting(None, Number(0.0, 1e3), "largest mean ΔLuv (eq. 2.2's average)")
    p95_dluv: float | None = setting(None, Number(0.0, 1e3), "largest 95th percentile of the per-pixel ΔLuv")
    flip: float | None = setting(None, Number(0.0, 1.0), "largest mean FLIP")
    iou: float | None = setting(None, Number(0.0, 1.0), "smallest coverage IoU")
    pop_dluv: float | None = setting(None, Number(0.0, 1e3), "largest pop: the mean ΔLuv between the two levels' "
                                     "frames at a switch size (what a viewer sees change); where the cheapest "
                                     "variant would pop more, the cheapest that does not is taken")
    hysteresis: float = setting(0.1, Number(0.0, 0.5), "around each switch size s, an engine switches to the coarser "
                                "level below s (1 - h) and back above s (1 + h), so a size hovering at s does not "
                                "flicker between levels (lod.json's switch_px)")
    limit_on: str = setting("change", Choice(*LIMIT_ON), "what the limits bound: `change`, each variant's frames "
                            "against the object's full asset drawn the same way (what a viewer sees change at a "
                            "switch; the full asset's own error against the reference is the floor, what the "
                            "pipeline costs whatever the representation), or `reference`, the error against the "
                            "reference")

    def limits(self) -> dict:
        """The limits given, by the report field they bound (`iou` a lower bound, the others upper bounds)."""
        return {LIMIT_ON[self.limit_on][k]: getattr(self, k) for k in LIMIT_ON[self.limit_on]
                if getattr(self, k) is not None}


@dataclass(frozen=True)
class Sweep:
    """Error and cost against screen size (vdmrender.views.sweep): every view again with the camera moved along its
    line of sight until the object's bounding sphere spans each size on screen; the frame size stays."""
    sizes: tuple[int, ...] = setting(REQUIRED, ListOf(Integer(2, 4 * MAX_SIDE)),
                                     "every view again with the object this many pixels across on screen (its bounding "
                                     "sphere's projected diameter; the camera moves, the frame stays; larger than the "
                                     "frame: the object overflows it): error and cost against screen size (sweep.csv, "
                                     "error_vs_size.png, cost_vs_size.png)", flag="PX,PX,...")
    lod: tuple[Thresholds, ...] = setting((), Tables(Thresholds),
                                          "[[render.sweep.lod]]: LOD chains to pick from the sweep (lod.json), one "
                                          "per set of limits: per size band the cheapest variant within them")


@dataclass(frozen=True)
class Render:
    resolution: tuple[int, int] = setting((512, 512), Vector(2, 1, MAX_SIDE, integer=True, sep="x"),
                                          "[width, height] in pixels", flag="WIDTHxHEIGHT")
    background: tuple[float, float, float] = setting((0.02, 0.022, 0.03), Vector(3, 0.0, 1.0),
                                                     "linear RGB behind the objects")
    repeats: int = setting(5, Integer(1, 1000), "timed renders of each frame, at least (`--sample-s` asks for time "
                           "too); the report gives their median GPU time", flag="N")
    warmup: int = setting(1, Integer(0, 100), "untimed renders of each frame before timing, at least, then on until "
                          "the GPU times are steady (`--warmup-s`); 0: no warm-up", flag="N")
    shadow_map: int = setting(2048, Integer(256, 16384), "shadow-map side in texels")
    composite: tuple = setting((), VariantSets(),
                               "composite frames: besides each object alone, every object of the scene in one frame "
                               "(one depth buffer, one shadow map of the whole scene; cameras framing every object), "
                               "once per variant set; each set names every object and one of its variants, e.g. "
                               '`[{ bunny = "mesh", torus = "vdm@8" }, { bunny = "coarse@0.1", torus = "pom@32" }]`; '
                               "the reference traces every object together")
    sweep: Sweep | None = setting(None, Table(Sweep), "[render.sweep]: error and cost against screen size, and LOD "
                                  "chains from them")
    reference_spp: int = setting(1, Square(MAX_SPP), "samples per pixel of the reference at most (the budget "
                                 "of the hardest pixels): N of the N x N stratified samples everywhere, the rest where "
                                 "they disagree (an edge, a shadow, texture), box-filtered in linear colour (what a "
                                 "viewer sees of the pixel; 1: the pixel centre only); the error that decides (sweeps, "
                                 "LOD chains) is against it, and every row also keeps the error against the "
                                 "pixel-centre reference (`aliased_*`)", flag="N")
    antialias: str = setting("none", Choice(*ANTIALIAS), "how each variant's frames are anti-aliased, as shipped: "
                             "`msaaN` N samples per pixel (GL multisampling: edges of triangles, not of what a "
                             "fragment stage discards), `ssaaK` rendered K x K larger and box-filtered down on the "
                             "GPU (timed and counted as the pass `resolve`)", flag="MODE")
    mipmaps: bool = setting(False, Boolean(), "mipmap the textures the techniques read (albedo maps, billboard "
                            "maps, octahedral atlases) and read VDM's tables at the level of the pixel's footprint "
                            "(Wang 2003 sec. 4); false: level 0 only")


@dataclass(frozen=True)
class Orbit:
    count: int = setting(4, Integer(1, 360), "cameras evenly around `camera.up`")
    elevation_deg: float = setting(20.0, Number(-89.0, 89.0), "elevation above the plane normal to `up`")
    azimuth_deg: float = setting(30.0, Number(-360.0, 360.0), "azimuth of the first camera")
    distance: float = setting(2.8, Number(1e-3, 1e4), "from the object's centre, in bounding-sphere radii")
    fov_deg: float = setting(40.0, Number(1.0, 175.0), "vertical field of view")


@dataclass(frozen=True)
class Pose:
    eye: tuple[float, float, float] = setting(REQUIRED, Vector(3), "camera position, scene units")
    target: tuple[float, float, float] = setting(REQUIRED, Vector(3), "point looked at (not the eye)")
    fov_deg: float = setting(40.0, Number(1.0, 175.0), "vertical field of view")


@dataclass(frozen=True)
class Cameras:
    up: tuple[float, float, float] = setting((0.0, 0.0, 1.0), Vector(3, nonzero=True), "world up of every camera")
    orbit: Orbit | None = setting(Orbit(), Table(Orbit),
                                  "cameras around each object (default unless only poses are given)")
    poses: tuple[Pose, ...] = setting((), Tables(Pose), "[[camera.poses]]: explicit cameras, absolute coordinates")


@dataclass(frozen=True)
class Light:
    direction: tuple[float, float, float] = setting((0.45, -0.55, 0.7), Direction(),
                                                    "towards the light (normalised on load)")
    color: tuple[float, float, float] = setting((1.0, 1.0, 1.0), Vector(3, 0.0, 1e3), "linear RGB")
    ambient: tuple[float, float, float] = setting((0.12, 0.12, 0.13), Vector(3, 0.0, 1e3),
                                                  "linear RGB; shadowed points get only this")

    def __post_init__(self):
        object.__setattr__(self, "direction", unit(self.direction))


@dataclass(frozen=True)
class Material:
    albedo: tuple[float, float, float] = setting((0.8, 0.76, 0.7), Vector(3, 0.0, 1.0), "linear RGB")
    diffuse: float = setting(1.0, Number(0.0, 10.0), "Lambert weight")
    specular: float = setting(0.25, Number(0.0, 10.0), "Blinn-Phong weight")
    shininess: float = setting(48.0, Number(1.0, 1e4), "Blinn-Phong exponent")


@dataclass(frozen=True)
class Transform:
    """Scale, then rotate about X, Y, Z (degrees), then translate."""
    scale: tuple[float, float, float] = setting((1.0, 1.0, 1.0), Vector(3, 1e-9, 1e9, scalar=True),
                                                "per axis (uniform for molecules and mesostructure frames)")
    rotate_deg: tuple[float, float, float] = setting((0.0, 0.0, 0.0), Vector(3), "about X, then Y, then Z")
    translate: tuple[float, float, float] = setting((0.0, 0.0, 0.0), Vector(3), "scene units")


@dataclass(frozen=True)
class Mesostructure:
    """Detail geometry over a surface object's UVs (Wang2003 §3): a height field tiled `tiling` times
    over the UV square, lying inward of the surface, `depth` deep in tile units (a tile spans 1 x 1);
    the VDM tables sample it `size`^2 texels x `phi` x `theta` views x `curvatures`."""
    height: str = setting(REQUIRED, Text(f"a pattern ({', '.join(PATTERNS)}), skimage:NAME "
                                         f"({', '.join(SKIMAGE_PHOTOS)}) or a PNG/EXR path (relative to the scene, "
                                         "or pkg:PACKAGE/PATH)"), "the height field, 1 = the surface")
    albedo: str | None = setting(None, Text(f"a colouring ({', '.join(meso_albedo.PATTERNS)}), skimage:NAME "
                                            f"({', '.join(meso_albedo.SKIMAGE_NAMES)}) or an 8-bit picture path (PNG, "
                                            "JPEG; relative to the scene, or pkg:PACKAGE/PATH)"),
                                 "colour tile (sRGB) repeating with the height field: the albedo of every mesostructure "
                                 "technique and of the reference, in place of the material's and the asset's own")
    size: int = setting(128, Integer(4, 1024), "texels per tile side")
    depth: float = setting(0.05, Number(0.0, 1.0), "depth of the mesostructure, tile units")
    tiling: tuple[float, float] = setting((1.0, 1.0), Vector(2, 1e-3, 1e4), "tiles over the UV square")
    phi: int = setting(32, Integer(1, 256), "VDM azimuth samples")
    theta: int = setting(8, Integer(1, 64), "VDM polar-angle samples")
    curvatures: int = setting(16, Integer(1, 64), "VDM curvature samples over the range the base mesh has")


@dataclass(frozen=True)
class Placement:
    """One instance: uniform scale, then rotate about X, Y, Z (degrees), then translate, all after the object's own
    transform and about its bounding-sphere centre (vdmbake.common.instances)."""
    translate: tuple[float, float, float] = setting((0.0, 0.0, 0.0), Vector(3), "scene units")
    rotate_deg: tuple[float, float, float] = setting((0.0, 0.0, 0.0), Vector(3), "about X, then Y, then Z")
    scale: float = setting(1.0, Number(1e-6, 1e6), "uniform (normals only turn)")


@dataclass(frozen=True)
class Scatter:
    """`count` instances at seeded random places of a rectangle of the plane through the object's centre normal
    to `camera.up`, each turned about `up` through its centre and scaled about it (vdmbake.common.instances)."""
    count: int = setting(REQUIRED, Integer(1, 1_000_000), "instances")
    area: tuple[float, float] = setting(REQUIRED, Vector(2, 0.0, 1e9), "sides of the rectangle, scene units, centred "
                                        "on the object")
    scale: tuple[float, float] = setting((1.0, 1.0), Vector(2, 1e-6, 1e6), "range of the uniform scale")
    rotate: bool = setting(True, Boolean(), "a random turn about `up` per instance")
    seed: int = setting(0, Integer(0, 2**63 - 1), "the generator's seed: the same seed, the same places")


@dataclass(frozen=True)
class Instances:
    """The object drawn many times from one bake (issue 23): an explicit list, or a seeded scatter."""
    placements: tuple[Placement, ...] = setting((), Tables(Placement), "[[objects.instances.placements]]: one table "
                                                "per instance")
    scatter: Scatter | None = setting(None, Table(Scatter), "a seeded scatter over a rectangle")


class Rows(Type):
    """Inline quadrics: rows of n finite numbers, the last (a radius) >= 0."""

    def __init__(self, n: int, shape: str):
        self.n, self.text = n, f"a list of {shape} rows of finite numbers, radius >= 0"

    def parse(self, raw):
        row = Vector(self.n)
        if not isinstance(raw, list):
            raise Invalid
        rows = tuple(row.parse(r) for r in raw)
        if any(r[-1] < 0 for r in rows):
            raise Invalid
        return rows

    def dump(self, value):
        return [list(r) for r in value]

_NAME = Text("1-64 characters from A-Z a-z 0-9 _ -", r"[A-Za-z0-9_-]{1,64}")
_PATH = Text("a file path (relative to the scene) or pkg:PACKAGE/PATH")


@dataclass(frozen=True, kw_only=True)
class Object:
    """One object; exactly one source: mesh, primitive, molecule, or spheres/cylinders."""
    name: str = setting(REQUIRED, _NAME, "unique name (output folders, report rows)")
    mesh: str | None = setting(None, _PATH, "a mesh file (glTF/GLB read here; OBJ, PLY, STL, ... through trimesh)")
    assets: str | None = setting(None, Text("a folder (relative to the scene file)"),
                                 "the folder inside which the files a mesh file names (glTF buffers and images, OBJ "
                                 "`mtllib` and `map_Kd`, PLY `TextureFile`) may lie, besides the mesh file's own "
                                 "folder; default: the scene file's folder. A name resolving elsewhere (an absolute "
                                 "path, `..` or a symbolic link leading out) is refused (exit 2)")
    textures: str = setting("use", Choice("use", "ignore"),
                            "the mesh file's own texture (OBJ `map_Kd` through its `mtllib`, glTF base colour, PLY "
                            "`TextureFile`): `use` it as the albedo (a texture that cannot be read is an error, exit "
                            "2), or `ignore` it (the material's albedo applies; neither the texture nor an OBJ's MTL "
                            "is read)")
    primitive: str | None = setting(None, Choice(*PRIMITIVES), "a built-in shape")
    params: object = setting(None, Custom("a table (see the primitives below)"), "the primitive's parameters")
    molecule: str | None = setting(None, _PATH, "a PDB or mmCIF file (gzipped too)")
    style: str | None = setting(None, Choice(*STYLES), f"molecule style (default {STYLES[0]!r})")
    spheres: tuple = setting((), Rows(4, "[x, y, z, radius]"), "inline spheres")
    cylinders: tuple = setting((), Rows(7, "[x0, y0, z0, x1, y1, z1, radius]"), "inline capped cylinders")
    transform: Transform = setting(Transform(), Table(Transform), "placement in the scene")
    material: Material = setting(Material(), Table(Material), "overrides of the scene's [material]")
    mesostructure: Mesostructure | None = setting(None, Table(Mesostructure),
                                                  "detail geometry over the surface's UVs (mesh or primitive)")
    techniques: dict = setting(REQUIRED, Custom("a table of technique tables (see the techniques below)"),
                               "the techniques to render and compare, each with its settings")
    instances: Instances | None = setting(None, Table(Instances),
                                          "[objects.instances]: draw the object many times from one bake (every "
                                          "technique, one instanced draw per pass; the reference traces every copy; "
                                          "not on objects with a mesostructure)")
    viewer_mesh: int | None = setting(None, Integer(0, 4),
                                      "quadrics objects: also bake them as one triangle mesh for viewers (standard PLY "
                                      "with vertex colours, part viewer-mesh), tessellated as `tessellated` draws them "
                                      "at this level")
    expect_empty: bool = setting(False, Boolean(), "the object may cover no pixel in every frame (a camera test); "
                                 "otherwise a variant none of whose frames has a covered pixel is an error (exit 2)")

    @property
    def kind(self) -> str:
        """Surfaces (a mesh file or a primitive) and quadrics (molecules, inline spheres/cylinders)
        are drawn by different techniques."""
        return "surface" if (self.mesh or self.primitive) else "quadrics"


@dataclass(frozen=True, kw_only=True)
class Scene:
    render: Render = setting(Render(), Table(Render), "[render]")
    camera: Cameras = setting(Cameras(), Table(Cameras), "[camera]")
    light: Light = setting(Light(), Table(Light), "[light]")
    material: Material = setting(Material(), Table(Material), "[material]: every object's default")
    objects: tuple[Object, ...] = setting(REQUIRED, Tables(Object), "[[objects]]")

    def to_dict(self) -> dict:
        """The resolved scene (every default filled in) as plain data; parse_scene_dict reads it back."""
        return dump(self)


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    try:
        text = read_regular(path, "scene file", limit=MAX_SCENE_BYTES).decode("utf-8")
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
    top = Reader(data, "", origin)
    material = top.value("material", Table(Material), Material())
    objects = top.data.get("objects")
    if not isinstance(objects, list) or not objects:
        raise InputError(f"{origin}: the scene needs at least one [[objects]] entry "
                         "(with 'mesh = PATH' or 'primitive = NAME').")
    objs = tuple(_object(Reader(o, f"objects[{i}]", origin), material) for i, o in enumerate(objects))
    names = [o.name for o in objs]
    for n in names:
        if names.count(n) > 1:
            raise InputError(f"{origin}: two objects are named {n!r}; object names must be unique.")
    render = top.value("render", Table(Render), Render())
    check_composite(render.composite, objs, origin)
    if render.composite and any(o.instances for o in objs):
        raise InputError(f"{origin}: render.composite with instanced objects is not drawn; render them alone.")
    check_sweep(render.sweep, origin)
    return read(Scene, top, render=render, material=material, objects=objs, camera=_cameras(top.table("camera")))


def variant_labels(obj: Object) -> list[str]:
    """The object's variant labels, as the report spells them (coarse@0.1, billboards@greedy-hier+coarse)."""
    return [REGISTRY[t].label(v) for t, options in obj.techniques.items() for v in REGISTRY[t].values(options)]


def check_composite(sets: tuple, objects: tuple, origin: str) -> None:
    """Every composite set names each object of the scene once, with one of its variant labels."""
    names = [o.name for o in objects]
    for i, s in enumerate(sets):
        where = f"render.composite[{i}]"
        for key, label in s.items():
            if key not in names:
                raise InputError(f"{origin}: key '{where}.{escaped(key)}' names no object of the scene; "
                                 f"its objects: {', '.join(names)}.")
            labels = variant_labels(next(o for o in objects if o.name == key))
            if label not in labels:
                raise InputError(f"{origin}: key '{where}.{key}' has value {label!r}, which is not a variant of "
                                 f"object {key!r}; its variants: {', '.join(labels)}.")
        missing = [n for n in names if n not in s]
        if missing:
            raise InputError(f"{origin}: [{where}] names no variant for {', '.join(map(repr, missing))}; a "
                             "composite frame holds every object of the scene, so each set names one variant "
                             "per object.")
        if s in sets[:i]:
            raise InputError(f"{origin}: [{where}] repeats an earlier set.")


def check_sweep(sweep: Sweep | None, origin: str) -> None:
    """Each LOD chain names at least one limit, and chains have distinct names."""
    names = [t.name for t in (sweep.lod if sweep else ())]
    for i, t in enumerate(sweep.lod if sweep else ()):
        if not t.limits():
            raise InputError(f"{origin}: [render.sweep.lod[{i}]] ({t.name!r}) gives no limit; give at least one of "
                             "mean_dluv, p95_dluv, flip, iou.")
        if names.count(t.name) > 1:
            raise InputError(f"{origin}: two LOD chains in [render.sweep.lod] are named {t.name!r}; names must be unique.")


def _cameras(t: Reader) -> Cameras:
    poses = t.value("poses", Tables(Pose), ())
    for i, p in enumerate(poses):
        if p.eye == p.target:
            Reader({}, f"camera.poses[{i}]", t.origin).fail("target", list(p.target), "a point different from eye")
    orbit = t.value("orbit", Table(Orbit), Orbit()) if not poses or t.has("orbit") else None
    return read(Cameras, t, orbit=orbit, poses=poses)


def _object(t: Reader, default_material: Material) -> Object:
    name = t.value("name", _NAME)
    sources = [k for k in ("mesh", "primitive", "molecule") if t.has(k)] + (
        ["spheres/cylinders"] if t.has("spheres") or t.has("cylinders") else [])
    if len(sources) != 1:
        raise InputError(f"{t.origin}: [{t.where}] (object {name!r}) needs exactly one source: 'mesh = PATH', "
                         f"'primitive = NAME' (NAME one of {', '.join(PRIMITIVES)}), 'molecule = PATH' "
                         f"(PDB or mmCIF), or inline 'spheres'/'cylinders' lists; it has "
                         f"{', '.join(sources) or 'none'}.")
    primitive = t.value("primitive", Choice(*PRIMITIVES), None)
    if primitive is not None:
        params = read(PRIMITIVES[primitive][1], t.table("params"))
    elif t.has("params"):
        t.fail("params", t.data["params"], "no params here (they belong to primitives)")
    else:
        params = None
    molecule = t.value("molecule", _PATH, None)
    if molecule is None and t.has("style"):
        t.fail("style", t.data["style"], "a style only for molecule objects")
    style = t.value("style", Choice(*STYLES), STYLES[0]) if molecule is not None else None
    mesh = t.value("mesh", _PATH, None)
    if (mesh or primitive) and t.has("viewer_mesh"):
        t.fail("viewer_mesh", t.data["viewer_mesh"], "a viewer mesh only for quadrics objects (molecules, spheres)")
    if t.has("mesostructure") and not (mesh or primitive):
        t.fail("mesostructure", t.data["mesostructure"], "a mesostructure only on mesh or primitive objects")
    meso = t.value("mesostructure", Table(Mesostructure), None)
    instances = t.value("instances", Table(Instances), None)
    if instances is not None:
        given = [k for k in ("placements", "scatter") if getattr(instances, k)]
        if len(given) != 1:
            t.fail("instances", t.data["instances"], "a table with exactly one of `placements` (a list of tables) "
                   "or `scatter`")
        if meso is not None:
            t.fail("instances", t.data["instances"], "instances only of objects without a mesostructure")
    m = t.table("material")    # the scene's material with the keys given here overridden
    material = read(Material, m, **{f: getattr(default_material, f) for f in vars(default_material) if not m.has(f)})
    kind = "surface" if (mesh or primitive) else "quadrics"
    techniques = _techniques(t.table("techniques"), name, kind, meso is not None)
    return read(Object, t, name=name, primitive=primitive, params=params, molecule=molecule, style=style, mesh=mesh,
                mesostructure=meso, material=material, techniques=techniques, instances=instances)


def _techniques(t: Reader, name: str, kind: str, has_meso: bool) -> dict:
    fitting = [k for k, spec in REGISTRY.items() if kind in spec.kinds]
    if not t.data:
        raise InputError(f"{t.origin}: object {name!r} has no [{t.where}]; name at least one of "
                         f"{', '.join(fitting)}, e.g. techniques = {{ {fitting[0]} = {{}} }}.")
    out = {}
    for tech in t.data:
        if tech not in REGISTRY:
            raise InputError(f"{t.origin}: unknown technique '{escaped(tech)}' in [{t.where}]; "
                             f"known techniques: {', '.join(REGISTRY)}.")
        spec = REGISTRY[tech]
        if kind not in spec.kinds:
            raise InputError(f"{t.origin}: technique '{tech}' in [{t.where}] does not draw {kind} objects "
                             f"like {name!r}; techniques for them: {', '.join(fitting)}.")
        if spec.mesostructure and not has_meso:
            raise InputError(f"{t.origin}: technique '{tech}' in [{t.where}] draws a mesostructure, but object "
                             f"{name!r} has none; add [objects.mesostructure] with height = PATTERN or PATH "
                             f"(patterns: {', '.join(PATTERNS)}).")
        out[tech] = read(spec.options, t.table(tech))
    return out
