"""Mesh files read into the shared triangle mesh (vdmbake.common.mesh.TriMesh): the file found (pkg: paths too) and
hashed, loaded through assets/references.py (every file a mesh file reaches is read and checked before trimesh sees
its bytes), coincident vertices merged, the asset's own colours and base-colour texture kept."""
from __future__ import annotations

import hashlib
import importlib.util
import io
import sys
import warnings
from pathlib import Path

import numpy as np

from ..common import texture
from ..common.colour import srgb8_to_linear
from ..common.mesh import TriMesh, validate, vertex_normals, weld
from ..errors import InputError, escaped
from .gltf import check_accessors, opened, read_gltf
from .references import check_picture, described, names_texture, reached_files


def merge_vertices(vertices: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None, colors: np.ndarray | None = None,
                   rel_tol: float = 1e-9):
    """Coincident vertices merged (STL and OBJ split them), tolerance relative to the mesh's size and
    about its centre, so that a mesh keeps its vertices at any scale and offset (an absolute tolerance
    welds a sphere 1e-8 across into a few points); vertices with different texture coordinates (UV
    seams) or colours stay apart. Returns vertices, faces, UVs and colours (None where none), first
    appearances kept in order."""
    key = weld(vertices, rel_tol)[:, None].astype(np.float64)
    if uvs is not None:
        finite = uvs[np.isfinite(uvs).all(1)]    # NaN and Inf (refused or dropped later) set no scale
        lo = finite.min(0) if len(finite) else np.zeros(2)
        span = max(float(np.abs(finite - lo).max()) if len(finite) else 0.0, 1e-300)
        key = np.column_stack([key, np.round((uvs - lo) / (span * rel_tol))])
    if colors is not None:
        key = np.column_stack([key, colors])
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    keep = first[order]
    return (vertices[keep], rank[inv.ravel()][faces], None if uvs is None else uvs[keep],
            None if colors is None else colors[keep])


def resolve_path(spec: str, base: Path) -> Path:
    """An input file's path relative to the scene file, or pkg:PACKAGE/PATH for a file shipped in a package."""
    if spec.startswith("pkg:"):
        package, _, inner = spec[4:].partition("/")
        # find_spec locates the package without importing it (some data-carrying packages
        # import heavy dependencies that the data does not need).
        found = importlib.util.find_spec(package) if package.isidentifier() else None
        if found is None or not found.submodule_search_locations:
            raise InputError(f"'{escaped(spec)}': Python package '{escaped(package)}' is not installed "
                             f"(pkg:PACKAGE/PATH names a file inside an installed package).")
        path = Path(next(iter(found.submodule_search_locations))) / inner
    else:
        path = (base / spec) if not Path(spec).is_absolute() else Path(spec)
    if not path.is_file():
        raise InputError(f"'{escaped(spec)}': file not found (looked at {escaped(str(path))}).")
    return path


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def load_mesh_file(path: Path, textures: bool = True, warn=None, root: Path | None = None) -> TriMesh:
    """Any format trimesh reads, merged to one triangle mesh with area-weighted vertex normals, and with its
    texture as an albedo map if `textures` and it has one. trimesh reads only the bytes of
    `references.reached_files`, through a resolver, and each texture file is checked first
    (`references.check_picture`); an embedded picture (a GLB's) over texture.MAX_PIXELS is left out undecoded.
    glTF is read here (gltf.read_gltf), not by trimesh: each primitive with its own material, and its NORMALs kept
    where it has them. `warn` hears what of the file was left out (default: printed to stderr). `root`: the folder
    besides the mesh file's own that the files it names may lie in (references.confined; the scene's folder)."""
    import trimesh  # imported here: only scenes with mesh files pay for it
    from PIL import Image

    warn = warn or (lambda m: print(f"warning: {m}", file=sys.stderr))
    shown = escaped(str(path))
    files = reached_files(path, str(path), textures, root, warn)
    for chain, f in files.items():
        if f.what == "texture":
            check_picture(f.data, f"{escaped(str(f.path))} (the {described(chain, f.what)})")
    resolver = {chain[-1]: f.data for chain, f in files.items() if len(chain) > 1}
    gltf = path.suffix[1:].lower() in ("gltf", "glb")
    if gltf:
        parsed = opened(files, shown)   # Draco decoded, before any check, so decoded data meets the plain checks
        check_accessors(parsed, shown)
    limit = Image.MAX_IMAGE_PIXELS
    try:
        Image.MAX_IMAGE_PIXELS = texture.MAX_PIXELS
        with warnings.catch_warnings():   # a picture over the limit: refused, not decoded with a warning
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            if gltf:
                loaded = read_gltf(files, parsed, textures, shown, warn)
            else:
                loaded = trimesh.load_scene(io.BytesIO(files[(str(path),)].data), resolver=resolver,
                                            file_type=trimesh.util.split_extension(path.name,
                                                                                   special=["tar.gz", "tar.bz2"]),
                                            process=False, skip_materials=not textures).to_mesh()
    except InputError:
        raise
    except ImportError as e:  # trimesh reads some formats through optional packages
        raise InputError(f"{shown}: format not supported here: install the Python package "
                         f"{e.name or 'that trimesh needs for it'} ({escaped(str(e))}).") from None
    except Exception as e:  # trimesh raises many types for unreadable files
        raise InputError(f"{shown}: cannot read the mesh ({type(e).__name__}: {escaped(str(e))}).") from None
    finally:
        Image.MAX_IMAGE_PIXELS = limit
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"{shown}: vertices of shape {vertices.shape}, not three coordinates each.")
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    validate(TriMesh(vertices, faces, np.zeros_like(vertices)), shown)
    if gltf:
        uv, albedo_map, colors, normals = loaded.uvs, loaded.texture, loaded.colors, loaded.normals
    else:
        visual = getattr(loaded, "visual", None)
        uv = getattr(visual, "uv", None)
        uv = np.asarray(uv, np.float64) if uv is not None else None
        uv = uv if uv is not None and uv.shape == (len(vertices), 2) else None
        albedo_map = base_colour_map(visual) if uv is not None else None
        colors, normals = vertex_colors(visual, len(vertices)), np.full_like(vertices, np.nan)
        if textures and albedo_map is None and names_texture(path.suffix[1:].lower(), files):
            raise InputError(f"{shown}: its material names a base-colour texture, but the mesh loads without one (no "
                             "texture coordinates for every vertex, a material trimesh cannot parse, or an embedded "
                             'picture it cannot decode); fix the file, or set textures = "ignore" on the object.')
    if albedo_map is not None and not np.isfinite(uv).all():
        raise InputError(f"{shown}: {int((~np.isfinite(uv)).any(1).sum())} vertices have NaN or Inf texture "
                         'coordinates, where its texture is read; fix the UVs, or set textures = "ignore" on the '
                         "object.")
    # Merge coincident vertices (STL and OBJ split them) so normals are smooth across faces; vertices with different
    # texture coordinates (UV seams), colours or file normals (hard edges) stay apart.
    given = np.isfinite(normals).all(1)
    keyed = np.where(given[:, None], normals, 2.0)    # 2: no normal from the file
    extra = keyed if colors is None else np.column_stack([np.asarray(colors, np.float64), keyed])
    v, f, uvs, extra = merge_vertices(vertices, faces, uv, extra)
    colors = None if colors is None else extra[:, :3]
    keyed = extra[:, -3:]
    # Normals over the surface, not over the UV charts: a vertex split at a UV seam gets the normal
    # of all its faces on both sides, so shading and displacement agree across the seam; the file's where it has
    # them (glTF NORMAL, §3.7.2.1: the normals it is meant to be shaded with).
    w = weld(v)
    n = vertex_normals(v[np.unique(w, return_index=True)[1]], w[f])[w]
    given = keyed[:, 0] != 2.0
    n[given] = keyed[given]
    return TriMesh(v, f, n, uvs, colors=colors, texture=albedo_map, file_normals=bool(given.any()))


def base_colour_map(visual) -> np.ndarray | None:
    """The asset's base-colour texture as an albedo map (vdmbake.common.texture), or None: OBJ's `map_Kd` as it is
    (as MeshLab and Blender show it: exporters write a default Kd beside a map), glTF's baseColorTexture as the
    file's own picture (its baseColorFactor is a colour per vertex: gltf_albedo)."""
    material = getattr(visual, "material", None)
    image = getattr(material, "baseColorTexture", None)
    if image is None:
        image = getattr(material, "image", None)
        if image is not None and image.format is None and not image.info:
            image = None   # made by trimesh for an OBJ with UVs and no material (a 2x2 grey), not the asset's
    return None if image is None else texture.from_image(image)


def vertex_colors(visual, count: int) -> np.ndarray | None:
    """(V, 3) linear per-vertex colours when the file has them as trimesh reads them, 8-bit sRGB (a vertex-kind
    visual, e.g. a PLY's red/green/blue properties or OBJ's `v x y z r g b`), else None."""
    if visual is None or getattr(visual, "kind", None) != "vertex":
        return None
    rgb = np.asarray(visual.vertex_colors)[:, :3]
    return srgb8_to_linear(rgb.astype(np.uint8)) if len(rgb) == count else None
