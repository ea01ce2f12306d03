"""The shared shading model in numpy: the twin of shaders/include/shading.glsl.

Lambert diffuse plus Blinn-Phong specular from one directional light, a constant ambient
term, ambient only where shadowed: linear radiance (encoded to 8-bit sRGB on output by
vdmbake.common.colour.to_srgb8).
"""
from __future__ import annotations

import numpy as np


def shade(albedo, normals, to_eye, lit, light, material) -> np.ndarray:
    """Linear radiance (N, 3). normals, to_eye: (N, 3) unit; lit: (N,) bool; light/material from the scene."""
    L = np.asarray(light.direction)
    albedo = np.broadcast_to(np.asarray(albedo, float), normals.shape)
    c = np.asarray(light.ambient) * albedo
    ndl = np.einsum("ij,j->i", normals, L)   # not @: BLAS's threads spin against the reference's (camera.pixel_rays)
    on = lit & (ndl > 0)
    h = L + to_eye
    H = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-8)
    spec = np.maximum(np.einsum("ij,ij->i", normals, H), 0.0) ** material.shininess
    direct = np.asarray(light.color) * (material.diffuse * ndl[:, None] * albedo + material.specular * spec[:, None])
    return c + np.where(on[:, None], direct, 0.0)


def safe_normalize(v: np.ndarray) -> np.ndarray:
    """Unit rows of any finite magnitude; a zero row stays zero (as safe_normalize in shading.glsl, which
    scales by the largest component first so that float32's squares hold)."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > 0, v / np.where(length > 0, length, 1.0), 0.0)
