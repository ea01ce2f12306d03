"""vdmrender over many bundles (issue 24): each rendered as alone into OUT/<name>/, one combined report keyed by
scene, object and variant, a failing bundle named and not stopping the others, --baseline on combined reports."""
import json

import pytest
from click.testing import CliRunner

from scenes import TINY_HEAD
from vdmbake.cli import main as bake_main
from vdmrender.cli import main as render_main

BALL = TINY_HEAD + '[[objects]]\nname = "ball"\nprimitive = "sphere"\ntechniques = { mesh = {}, coarse = { ratios = [0.2] } }\n'
CONE = TINY_HEAD + '[[objects]]\nname = "cone"\nprimitive = "cone"\ntechniques = { mesh = {} }\n'


@pytest.fixture
def library(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "ball.toml").write_text(BALL)
    (scenes / "cone.toml").write_text(CONE)
    r = CliRunner().invoke(bake_main, [str(scenes), "-o", str(tmp_path / "bundles"), "--jobs", "1"])
    assert r.exit_code == 0, r.output
    return tmp_path / "bundles"


@pytest.mark.gl
@pytest.mark.plots
def test_a_folder_of_bundles_renders_each_and_combines_the_rows(library, tmp_path):
    out = tmp_path / "renders"
    r = CliRunner().invoke(render_main, [str(library), "-o", str(out), "--no-flip"])
    assert r.exit_code == 0, r.output
    combined = json.loads((out / "report.json").read_text())
    assert [(x["scene"], x["status"]) for x in combined["runs"]] == [("ball", "rendered"), ("cone", "rendered")]
    assert {(x["scene"], x["object"], x["label"]) for x in combined["rows"]} == {
        ("ball", "ball/ball", "mesh"), ("ball", "ball/ball", "coarse@0.2"), ("cone", "cone/cone", "mesh")}
    for scene in ("ball", "cone"):   # each run as alone
        alone = json.loads((out / scene / "report.json").read_text())
        assert len(alone["rows"]) == sum(x["scene"] == scene for x in combined["rows"])
    for name in ("report.csv", "error_vs_time.png", "runs.md"):
        assert (out / name).is_file()
    again = CliRunner().invoke(render_main, [str(library), "-o", str(tmp_path / "again"), "--no-flip", "--baseline",
                                             str(out / "report.json"), "--max-error-increase", "0.01"])
    assert again.exit_code == 0, again.output
    block = json.loads((tmp_path / "again" / "report.json").read_text())["baseline"]
    assert {c["status"] for c in block["rows"]} == {"compared"} and len(block["rows"]) == 3
    assert all(abs(c["d_mean_dluv"]) < 1e-9 for c in block["rows"])   # deterministic frames and references


@pytest.mark.gl
def test_a_failing_bundle_is_named_and_the_others_render(library, tmp_path):
    broken = library / "zzz.bundle"
    broken.mkdir()
    (broken / "manifest.json").write_text("{}")
    out = tmp_path / "renders"
    r = CliRunner().invoke(render_main, [str(library), "-o", str(out), "--no-flip"])
    assert r.exit_code == 1 and "1 of 3 bundles failed: zzz" in r.output, r.output
    runs = {x["scene"]: x for x in json.loads((out / "report.json").read_text())["runs"]}
    assert runs["zzz"]["status"] == "failed" and "format" in runs["zzz"]["reason"]
    assert runs["ball"]["status"] == runs["cone"]["status"] == "rendered"
    assert not (out / "zzz").exists()


def test_bundles_of_one_name_and_empty_folders_are_refused(tmp_path):
    for d in ("a/x.bundle", "b/x"):
        (tmp_path / d).mkdir(parents=True)
        (tmp_path / d / "manifest.json").write_text("{}")
    r = CliRunner().invoke(render_main, [str(tmp_path / "a/x.bundle"), str(tmp_path / "b/x"), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "named 'x'" in r.output, r.output
    (tmp_path / "empty").mkdir()
    r = CliRunner().invoke(render_main, [str(tmp_path / "empty"), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "not a bundle (no manifest.json), nor a folder holding bundles" in r.output, r.output


@pytest.mark.gl
def test_a_bundle_failing_with_any_error_is_named_and_the_others_render(library, tmp_path, monkeypatch):
    """Not only the tool's own refusals: a GL, library or OS error in one bundle is that bundle's failure (issue 34),
    and the combined report says what the runs' errors are against."""
    from vdmrender import many

    real = many.run

    def flaky(path, out, opts, log):
        if path.name == "ball.bundle":
            raise RuntimeError("the GL driver lost the context")
        return real(path, out, opts, log)

    monkeypatch.setattr(many, "run", flaky)
    out = tmp_path / "renders"
    r = CliRunner().invoke(render_main, [str(library), "-o", str(out), "--no-flip", "--reference-spp", "4"])
    assert r.exit_code == 1 and "1 of 2 bundles failed: ball" in r.output, r.output
    combined = json.loads((out / "report.json").read_text())
    runs = {x["scene"]: x for x in combined["runs"]}
    assert runs["ball"]["status"] == "failed" and "RuntimeError: the GL driver lost" in runs["ball"]["reason"]
    assert runs["cone"]["status"] == "rendered" and combined["filtering"]["reference_spp"] == 4


@pytest.mark.gl
@pytest.mark.slow
@pytest.mark.plots
def test_the_combined_folder_is_swapped_in_whole(library, tmp_path, monkeypatch):
    """OUT is staged as every output folder is: a run that fails while combining leaves the previous OUT exactly as
    it was (no half-written combined report beside new runs), and the next run finds each bundle's cached
    references through its staging copy."""
    from vdmrender import many

    out = tmp_path / "renders"
    assert CliRunner().invoke(render_main, [str(library), "-o", str(out), "--no-flip"]).exit_code == 0
    before = {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}

    def broken(folder, result):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(many.html, "write", broken)
    r = CliRunner().invoke(render_main, [str(library), "-o", str(out), "--no-flip", "--resolution", "24x24"])
    assert r.exit_code != 0
    after = {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    assert after == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".renders.")] == []
    monkeypatch.undo()
    r = CliRunner().invoke(render_main, [str(library), "-o", str(out), "--no-flip"])
    assert r.exit_code == 0, r.output
    rows = json.loads((out / "report.json").read_text())["rows"]
    assert rows and all(x["reference_cached"] for x in rows)


@pytest.mark.plots
def test_every_bundle_failing_is_exit_1_with_the_table(tmp_path):
    """No bundle rendered: the combined report has no rows and no plot, and the run ends as any failure does."""
    folder = tmp_path / "bundles"
    for name in ("a", "b"):
        (folder / f"{name}.bundle").mkdir(parents=True)
        (folder / f"{name}.bundle" / "manifest.json").write_text("{}")
    out = tmp_path / "renders"
    r = CliRunner().invoke(render_main, [str(folder), "-o", str(out), "--no-flip"])
    assert r.exit_code == 1 and "2 of 2 bundles failed" in r.output, r.output
    assert json.loads((out / "report.json").read_text())["rows"] == []
    assert (out / "report.html").is_file() and not (out / "error_vs_time.png").exists()
