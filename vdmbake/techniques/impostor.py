"""Technique `impostor`: spheres and capped cylinders ray cast per pixel (Sigg et al. 2006; de Poel &
Bresser 2009). Needs only the quadric list, which every quadrics object has."""
from __future__ import annotations

from dataclasses import dataclass

from ..schema import Choice, ListOf, Number, Technique, setting


@dataclass(frozen=True)
class Options:
    shading: tuple[str, ...] = setting(("direct", "deferred", "outlines"),
                                       ListOf(Choice("direct", "deferred", "outlines")),
                                       "direct; deferred (G-buffer of normal and mu); outlines (deferred + Sobel "
                                       "silhouettes and creases)", knob="shading")
    silhouette: float = setting(1.0, Number(0.0, 100.0), "strength of the Sobel silhouette outline (depth edges)")
    crease: float = setting(1.0, Number(0.0, 100.0), "strength of the Sobel crease outline (normal edges)")


TECHNIQUE = Technique("impostor", "spheres and capped cylinders ray cast per pixel on Sigg's perspective-correct "
                      "bounding boxes, stable quadratic, exact depth", ("quadrics",), Options)
