"""What is drawn beyond one object from its own cameras: `camera` (cameras framing an object or a size on
screen), `sweep` (each view at given sizes on screen), `composite` (every object in one frame) and `lodmix`
(a chain drawn per copy as an engine would)."""
