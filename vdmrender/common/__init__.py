"""What every room of the renderer shares, with no GL: `camera` (the camera model and cameras framing an
object), `images` (frames and heat maps as PNG and EXR files), `markdown` (figures and names as Markdown text),
`plots` (the axes every plot shares) and `progress` (progress lines on stderr)."""
