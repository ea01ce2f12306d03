"""Scene snippets shared by the tests: small enough that a bake and a render take well under a second."""

RENDER = """\
[render]
resolution = [32, 32]
repeats = 1
warmup = 0
shadow_map = 256
"""
CAMERA = """
[camera]
orbit = { count = 1 }
"""
TINY_HEAD = RENDER + CAMERA
