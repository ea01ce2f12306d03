"""Raw control characters in names the user gives (scene files, bundles, output folders) are escaped in every
progress and log line the tools print (issue 32): an escape sequence in a scene file's name recoloured the
terminal and a newline split a progress line. One escaping function does it everywhere (vdmbake.errors.escaped)."""
import re

import pytest
from click.testing import CliRunner

from scenes import RENDER
from vdmbake import errors, schema
from vdmbake.cli import main as bake_main

EVIL = "red\x1b[31m\nline\u202e"                     # an escape sequence, a newline, a bidi override
SHOWN = "red\\x1b[31m\\nline\\u202e"
SCENE = RENDER + '[[objects]]\nname = "ball"\nprimitive = "sphere"\ntechniques = { mesh = {} }\n'


def _clean(output: str) -> None:
    """No raw control character and no line that starts inside a name."""
    assert "\x1b" not in output and "\u202e" not in output, repr(output)
    assert not [line for line in output.splitlines() if line.startswith("line")], repr(output)


def test_one_escaping_function():
    """No module of the tools defines an escaping of its own or another name for errors.escaped."""
    from pathlib import Path

    root = Path(errors.__file__).parents[1]
    for path in [*root.glob("vdmbake/**/*.py"), *root.glob("vdmrender/**/*.py")]:
        text = path.read_text()
        assert not re.search(r"^def \w*(escap|printable)", text, re.M) or path.name == "errors.py", path
        assert not re.search(r"^\w+ = escaped\b", text, re.M), path
    assert not hasattr(schema, "printable")
    assert errors.escaped(EVIL) == SHOWN and errors.escaped("plain/it's \\ fine") == "plain/it's \\ fine"


def test_one_shortening_function():
    """A value quoted in a message is escaped and shortened by errors.cut alone (schema.show too): no module cuts
    one by hand (a hash's 12-digit short form is not a quoted value)."""
    from pathlib import Path

    root = Path(errors.__file__).parents[1]
    for path in [*root.glob("vdmbake/**/*.py"), *root.glob("vdmrender/**/*.py")]:
        cuts = re.findall(r"\b(?:escaped|str|repr)\(.*?\)\[:(\d+)\]", path.read_text())
        assert all(int(n) < 40 for n in cuts), (path, cuts)
    assert errors.cut(EVIL) == SHOWN and errors.cut("x" * 201) == "x" * 200 + "..." and errors.cut("x" * 200) == "x" * 200
    assert errors.cut(EVIL, 4) == SHOWN[:4] + "..." and schema.show("x" * 300) == repr("x" * 300)[:200] + "..."


def test_one_scene_log_lines_are_escaped(tmp_path):
    """Failed before the fix: the log line `OUT: baking (...)` and `baked OUT` printed the name raw."""
    (tmp_path / f"{EVIL}.toml").write_text(SCENE)
    r = CliRunner().invoke(bake_main, [str(tmp_path / f"{EVIL}.toml"), "-o", str(tmp_path / f"{EVIL}.bundle")],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 0, r.output
    _clean(r.output)
    assert f"{SHOWN}.bundle: baking" in r.output and f"baked {tmp_path}/{SHOWN}.bundle" in r.output


def test_batch_progress_and_table_are_escaped(tmp_path):
    """Failed before the fix: each progress line and the closing table printed the scene file's name raw."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / f"{EVIL}.toml").write_text(SCENE)
    (scenes / f"bad{EVIL}.toml").write_text("[[objects]]\nname = 3\n")
    r = CliRunner().invoke(bake_main, [str(scenes), "-o", str(tmp_path / "out"), "--jobs", "1"],
                           env={"VDM_CACHE": None})
    assert r.exit_code == 1, r.output
    _clean(r.output)
    assert f"] {SHOWN}.toml: baked" in r.output and re.search(re.escape(f"\n{SHOWN}.toml ") + " +baked", r.output)
    assert f"scenes failed: {scenes}/bad{SHOWN}.toml" in r.output


@pytest.mark.gl
def test_render_log_lines_are_escaped(tmp_path):
    from vdmrender.cli import main as render_main

    (tmp_path / "s.toml").write_text(SCENE)
    bundle = tmp_path / f"{EVIL}.bundle"
    assert CliRunner().invoke(bake_main, [str(tmp_path / "s.toml"), "-o", str(bundle)]).exit_code == 0
    r = CliRunner().invoke(render_main, [str(bundle), "-o", str(tmp_path / f"out{EVIL}"), "--no-flip"])
    assert r.exit_code == 0, r.output
    _clean(r.output)
    assert f"out{SHOWN}/report.html" in r.output
