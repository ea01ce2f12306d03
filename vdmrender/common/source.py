"""What is drawn and traced of an object, read from its bundle: a `Source` is what a renderer builds from, and
what the reference and the full asset read their geometry through."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from vdmbake.common import instances
from vdmbake.scene import Object, Scene


@dataclass
class Source:
    """What a renderer builds from: the object, its manifest entry, the technique's own entry (the
    parts its bake wrote; None if it bakes none), the bundle and the scene, and its settings."""
    obj: Object
    entry: dict
    part: dict | None
    bundle: Any
    scene: Scene
    options: Any

    @property
    def shadow_map(self) -> int:
        return self.scene.render.shadow_map

    @property
    def mipmaps(self) -> bool:
        """The scene's render.mipmaps: textures and tables read at the pixel footprint's mip level."""
        return self.scene.render.mipmaps

    @property
    def instances(self):
        """(N, 4, 4) world matrices of the object's copies (vdmbake.common.instances); None: drawn once."""
        i = self.obj.instances
        return None if i is None else instances.matrices(i, self.scene.camera.up, self.entry["centre"])
