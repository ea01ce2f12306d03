"""The viewer mesh of a quadrics object (issue 12): its spheres and cylinders tessellated into one standard
PLY with vertex colours, which trimesh and MeshLab open, where the exact `quadrics` part shows as nothing."""
from __future__ import annotations

import numpy as np
import pytest

from scenes import TINY_HEAD
from vdmbake.bundle import parts
from vdmbake.kernels import quadric_mesh
from vdmbake.bundle.directory import Bundle
from vdmbake.errors import InputError
from vdmbake.kernels.quadrics import QuadricSet
from vdmbake.scene import parse_scene_dict

RED, BLUE = [0.8, 0.05, 0.05], [0.05, 0.1, 0.9]


def two_quadrics() -> QuadricSet:
    """A sphere of radius 0.7 and a cylinder of radius 0.3 and length 3 along a skew axis, far off."""
    far = np.array([1e3, -2e3, 5e2])
    return QuadricSet(np.array([[*far, 0.7]]), np.array([RED], np.float32),
                      np.array([[*(far + [1, 0, 0]), *(far + [1, 0, 0] + 3 * np.array([0.48, 0.6, 0.64])), 0.3]]),
                      np.array([BLUE], np.float32))


def test_tessellation_is_closed_outward_and_coloured():
    """Each quadric is a closed, outward-facing shell: trimesh's volume of each is its analytic volume less
    the tessellation's chord loss (level 3: 0.86% for the icosphere, 0.64% for the 32-sided prism), colours
    are the quadric's albedo in sRGB8, and the positions keep the quadrics' place far from the origin."""
    import trimesh
    q = two_quadrics()
    mesh, rgb = quadric_mesh.tessellate(q, 3)
    n_sphere = 20 * 4 ** 3                         # spheres' faces first, then the cylinders'
    sphere, cylinder = (trimesh.Trimesh(mesh.vertices, f) for f in (mesh.faces[:n_sphere], mesh.faces[n_sphere:]))
    assert sphere.is_watertight and cylinder.is_watertight   # once the caps' rims are merged with the side's
    assert sphere.volume == pytest.approx(4 / 3 * np.pi * 0.7 ** 3, rel=0.02)     # measured -0.86%
    assert cylinder.volume == pytest.approx(np.pi * 0.3 ** 2 * 3.0, rel=0.02)      # measured -0.64%
    assert sphere.volume < 4 / 3 * np.pi * 0.7 ** 3 and cylinder.volume < np.pi * 0.3 ** 2 * 3.0
    np.testing.assert_allclose(sphere.centroid, q.spheres[0, :3], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-12)
    back, srgb = parts.stored(parts.VIEWER_MESH, (mesh, rgb))
    assert set(map(tuple, srgb)) == {(231, 63, 63), (63, 89, 243)}   # sRGB of 0.8, 0.05; 0.05, 0.1, 0.9
    assert np.abs(back.vertices - mesh.vertices).max() < 2.5e-4   # float32 for viewers: spacing 2.4e-4 at 2e3


def test_baked_part_opens_in_trimesh(tmp_path):
    """Scene -> bundle: `viewer_mesh = 1` bakes a viewer-mesh part beside the exact quadric list; trimesh
    reads the part as a coloured triangle mesh of 80 faces per sphere and 32 per cylinder (8 sides, two 8-triangle caps), and reads the
    quadrics part as no geometry at all (the reason for the part)."""
    import trimesh
    from click.testing import CliRunner

    from vdmbake.cli import main as bake_main

    scene = tmp_path / "s.toml"
    scene.write_text(TINY_HEAD + '[[objects]]\nname = "q"\nspheres = [[0, 0, 0, 1], [2, 0, 0, 0.5]]\n'
                     'cylinders = [[0, 0, 0, 2, 0, 0, 0.2]]\nviewer_mesh = 1\ntechniques = { impostor = {} }\n')
    r = CliRunner().invoke(bake_main, [str(scene), "-o", str(tmp_path / "b.bundle")])
    assert r.exit_code == 0, r.output
    bundle = Bundle(tmp_path / "b.bundle")
    entry = bundle.manifest["objects"]["q"]
    assert bundle.manifest["parts"][entry["viewer_mesh"]]["faces"] == 2 * 80 + 32
    loaded = trimesh.load(str(tmp_path / "b.bundle" / entry["viewer_mesh"]), process=False)
    assert isinstance(loaded, trimesh.Trimesh) and len(loaded.faces) == 2 * 80 + 32
    assert loaded.visual.kind == "vertex" and loaded.is_winding_consistent
    exact = trimesh.load(str(tmp_path / "b.bundle" / entry["quadrics"]))
    assert len(getattr(exact, "faces", [])) == 0 and len(getattr(exact, "vertices", [])) == 0


def test_viewer_mesh_only_for_quadrics():
    with pytest.raises(InputError, match="viewer_mesh"):
        parse_scene_dict({"objects": [{"name": "t", "primitive": "torus", "viewer_mesh": 1,
                                       "techniques": {"mesh": {}}}]}, "scene")
