"""vdmrender.common.camera: bases, view/projection matrices, pixel rays (the contract shared by the GL
path and the CPU reference), clip planes, orbit placement and degenerate poses."""
from __future__ import annotations

import numpy as np
import pytest

from vdmbake.scene import Cameras as SceneCamera, Orbit, Pose
from vdmrender.common.camera import Camera, cameras_for, clip_planes, orbit

CENTRE = np.array([0.3, -1.2, 0.8])
RADIUS = 1.7


def _cam(eye=(4.0, -3.0, 2.5), target=CENTRE, up=(0.0, 0.0, 1.0), fov=40.0, w=64, h=48) -> Camera:
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    return Camera(eye, target, np.asarray(up, float), fov, w, h, *clip_planes(eye, target, CENTRE, RADIUS))


def _check_basis(b):
    assert np.isfinite(b).all()
    np.testing.assert_allclose(b @ b.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(b) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(np.cross(b[0], b[1]), b[2], atol=1e-12)  # right x up = back


def _ndc(cam, points):
    ph = np.hstack([points, np.ones((len(points), 1))])
    clip = ph @ (cam.projection() @ cam.view()).T
    return clip[:, :3] / clip[:, 3:4], clip[:, 3]


POSES = [
    dict(),
    dict(eye=(-2.0, 5.0, -1.0), up=(0.0, 1.0, 0.0)),
    dict(eye=(0.0, 0.0, 10.0), target=(0.1, 0.2, 0.0), up=(0.0, 0.0, 3.0)),  # nearly along up, non-unit up
    dict(eye=(1e5, 2e5, -3e5), target=(1e5 + 1, 2e5 + 2, -3e5 + 1)),
]


@pytest.mark.parametrize("kw", POSES)
def test_basis_orthonormal_right_handed(kw):
    cam = _cam(**kw)
    b = cam.basis()
    _check_basis(b)
    # back points from the target to the eye; up is on the side of the requested up
    fwd = cam.target - cam.eye
    np.testing.assert_allclose(b[2], -fwd / np.linalg.norm(fwd), atol=1e-12)
    assert np.dot(b[1], cam.up) > 0


@pytest.mark.parametrize("kw", POSES)
def test_view_maps_eye_to_origin_and_target_to_minus_z(kw):
    cam = _cam(**kw)
    v = cam.view()
    np.testing.assert_allclose(v[3], [0, 0, 0, 1])
    scale = np.linalg.norm(cam.eye) + 1.0
    np.testing.assert_allclose(v @ np.append(cam.eye, 1.0), [0, 0, 0, 1], atol=1e-12 * scale)
    dist = np.linalg.norm(cam.target - cam.eye)
    np.testing.assert_allclose(v @ np.append(cam.target, 1.0), [0, 0, -dist, 1], atol=1e-12 * scale)
    # a rigid transform: lengths kept
    np.testing.assert_allclose(v[:3, :3] @ v[:3, :3].T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("fov", [40.0, 90.0, 120.0, 170.0])
@pytest.mark.parametrize("w,h", [(64, 48), (31, 57)])
def test_pixel_rays_project_to_pixel_centres(fov, w, h):
    """The GL/reference contract: a point on pixel (x, y)'s ray lands, under projection @ view,
    at NDC ((x+0.5)/W*2-1, 1-(y+0.5)/H*2), row 0 at the top, at any depth in [near, far];
    the near plane maps to NDC z = -1 and the far plane to +1 (GL)."""
    cam = _cam(fov=fov, w=w, h=h)
    eye, d = cam.pixel_rays()
    assert eye.shape == d.shape == (w * h, 3)
    assert np.isfinite(d).all()
    np.testing.assert_array_equal(eye[0], cam.eye)
    rng = np.random.default_rng(int(fov) + w)
    idx = rng.integers(0, w * h, size=40)
    idx[:2] = [0, w * h - 1]  # top-left and bottom-right corners
    y, x = np.divmod(idx, w)
    expected = np.stack([(x + 0.5) / w * 2 - 1, 1 - (y + 0.5) / h * 2], 1)
    for s, z_ndc in [(cam.near, -1.0), (0.5 * (cam.near + cam.far), None), (cam.far, 1.0)]:
        ndc, wclip = _ndc(cam, eye[idx] + s * d[idx])
        np.testing.assert_allclose(wclip, s, rtol=1e-9)  # clip w is view depth
        np.testing.assert_allclose(ndc[:, :2], expected, atol=1e-9)
        if z_ndc is not None:
            np.testing.assert_allclose(ndc[:, 2], z_ndc, atol=1e-6)


def test_pixel_rays_row_major_top_row_first():
    cam = _cam(w=5, h=3)
    _, d = cam.pixel_rays()
    b = cam.basis()
    dc = d @ b.T  # camera space
    grid = dc.reshape(3, 5, 3)
    assert (np.diff(grid[:, :, 0], axis=1) > 0).all()  # x grows to the right along a row
    assert (np.diff(grid[:, :, 1], axis=0) < 0).all()  # rows go down the image
    assert grid[0, 0, 1] > 0 and grid[0, 0, 0] < 0   # pixel 0 is top-left


@pytest.mark.parametrize("kw", POSES)
def test_pixel_ray_camera_space_z_is_minus_one(kw):
    cam = _cam(**kw)
    _, d = cam.pixel_rays()
    dc = d @ cam.basis().T
    np.testing.assert_allclose(dc[:, 2], -1.0, rtol=0, atol=1e-14)
    # so the ray parameter is view depth: the target's depth equals its distance
    dist = np.linalg.norm(cam.target - cam.eye)
    centre_ray = np.array([0.0, 0.0, -1.0]) @ cam.basis()
    np.testing.assert_allclose(cam.eye + dist * centre_ray, cam.target, atol=1e-9 * (1 + dist))


@pytest.mark.parametrize("eye", [(8.0, 1.0, -2.0), (2.0, -1.0, 1.5), (0.5, -1.0, 0.9), tuple(CENTRE)])
def test_clip_planes_enclose_bounding_sphere(eye):
    eye = np.asarray(eye, float)
    target = CENTRE + np.array([0.4, 0.1, -0.2]) if np.allclose(eye, CENTRE) else CENTRE
    near, far = clip_planes(eye, target, CENTRE, RADIUS)
    assert 0 < near < far and np.isfinite(far)
    fwd = (target - eye) / np.linalg.norm(target - eye)
    rng = np.random.default_rng(0)
    u = rng.normal(size=(2000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u = np.vstack([u, fwd, -fwd])
    depth = (CENTRE + RADIUS * u - eye) @ fwd
    assert depth.max() <= far
    inside = np.linalg.norm(eye - CENTRE) < RADIUS
    if inside:
        # the eye is inside: nothing to hug in front, but near stays positive and small
        assert near <= 1e-3 * far
    else:
        assert depth.min() >= near


@pytest.mark.parametrize("spec,up", [
    (Orbit(count=5, elevation_deg=20.0, azimuth_deg=30.0, distance=2.8, fov_deg=40.0), (0.0, 0.0, 1.0)),
    (Orbit(count=3, elevation_deg=-35.0, azimuth_deg=0.0, distance=4.0, fov_deg=60.0), (0.0, 2.0, 0.0)),
    (Orbit(count=4, elevation_deg=60.0, azimuth_deg=10.0, distance=1.5, fov_deg=30.0), (1.0, 1.0, 0.5)),
])
def test_orbit_distance_elevation_and_spacing(spec, up):
    cams = orbit(spec, up, CENTRE, RADIUS, 40, 30)
    assert len(cams) == spec.count
    upn = np.asarray(up) / np.linalg.norm(up)
    offs = np.array([c.eye - CENTRE for c in cams])
    np.testing.assert_allclose(np.linalg.norm(offs, axis=1), spec.distance * RADIUS, rtol=1e-12)
    elev = np.degrees(np.arcsin(offs @ upn / np.linalg.norm(offs, axis=1)))
    np.testing.assert_allclose(elev, spec.elevation_deg, atol=1e-9)
    # evenly spaced in azimuth about `up`
    flat = offs - np.outer(offs @ upn, upn)
    flat /= np.linalg.norm(flat, axis=1, keepdims=True)
    step = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", flat, np.roll(flat, -1, 0)), -1, 1)))
    np.testing.assert_allclose(step, 360.0 / spec.count, atol=1e-9)
    turn = np.einsum("ij,ij->i", np.cross(flat, np.roll(flat, -1, 0)), np.tile(upn, (len(flat), 1)))
    assert (turn > 0).all()  # counter-clockwise about up
    for c in cams:
        np.testing.assert_array_equal(c.target, CENTRE)
        assert c.fov_deg == spec.fov_deg and (c.width, c.height) == (40, 30)
        assert 0 < c.near < spec.distance * RADIUS - RADIUS and c.far > spec.distance * RADIUS + RADIUS
        _check_basis(c.basis())
        ndc, _ = _ndc(c, CENTRE[None])
        np.testing.assert_allclose(ndc[0, :2], 0.0, atol=1e-12)  # the centre is in the middle


@pytest.mark.parametrize("elev", [89.0, 90.0, -90.0])
def test_orbit_looking_along_up_is_finite(elev):
    cams = orbit(Orbit(count=4, elevation_deg=elev, distance=3.0), (0.0, 0.0, 1.0), CENTRE, RADIUS, 32, 32)
    for c in cams:
        b = c.basis()
        _check_basis(b)
        np.testing.assert_allclose(b[2], np.sign(elev) * np.array([0, 0, 1.0]), atol=0.02)
        _, d = c.pixel_rays()
        assert np.isfinite(d).all()
        ndc, _ = _ndc(c, CENTRE[None])
        np.testing.assert_allclose(ndc[0, :2], 0.0, atol=1e-9)


@pytest.mark.parametrize("up", [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])
def test_pose_eye_directly_above_target(up):
    up = np.asarray(up)
    target = np.array([1.0, 2.0, 3.0])
    for sign in (1.0, -1.0):
        cam = _cam(eye=target + sign * 4.0 * up, target=target, up=up)
        _check_basis(cam.basis())
        v = cam.view()
        assert np.isfinite(v).all()
        np.testing.assert_allclose(v @ np.append(target, 1.0), [0, 0, -4.0, 1], atol=1e-12)
        _, d = cam.pixel_rays()
        assert np.isfinite(d).all()
        np.testing.assert_allclose((d @ cam.basis().T)[:, 2], -1.0, atol=1e-14)


@pytest.mark.parametrize("fov", [120.0, 170.0])
def test_wide_fov_rays_finite(fov):
    cam = _cam(fov=fov, w=33, h=17)
    eye, d = cam.pixel_rays()
    assert np.isfinite(d).all() and np.isfinite(cam.projection()).all()
    # the corner ray's angle to the axis is at most the half-diagonal angle and grows with fov
    t = np.tan(np.radians(fov) / 2)
    corner = np.array([(-1 + 1 / 33) * t * 33 / 17, (1 - 1 / 17) * t, -1.0])
    dc = d @ cam.basis().T
    np.testing.assert_allclose(dc[0], corner, rtol=1e-12)


def test_cameras_for_orbit_then_poses():
    sc = SceneCamera(up=(0.0, 0.0, 1.0), orbit=Orbit(count=2),
                     poses=(Pose(eye=(0.0, 0.0, 9.0), target=tuple(CENTRE), fov_deg=25.0),))
    cams = cameras_for(sc, CENTRE, RADIUS, 20, 10)
    assert len(cams) == 3
    assert cams[2].fov_deg == 25.0
    np.testing.assert_array_equal(cams[2].eye, [0.0, 0.0, 9.0])
    near, far = clip_planes(cams[2].eye, cams[2].target, CENTRE, RADIUS)
    assert (cams[2].near, cams[2].far) == (near, far)
    for c in cams:
        _check_basis(c.basis())
