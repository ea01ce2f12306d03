"""bench.suite (what the test suite costs): a run's counts come from pytest's own summary, each test's CPU seconds
from the plugin, the sums by file and over another commit's tests from those rows; failures are counted and said
by the exit code."""
import json
import re
import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner

from bench import suite, tables

ROOT = Path(__file__).resolve().parents[1]


def test_a_run_of_one_file_with_the_tests_of_a_commit(tmp_path):
    r = CliRunner().invoke(suite.main, ["-o", str(tmp_path), "--workers", "0", "--ids-of", "HEAD", "--",
                                        "tests/test_markdown.py"])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "suite.json").read_text())
    ids = subprocess.run([sys.executable, "-m", "pytest", "-q", "--collect-only", "tests/test_markdown.py"], cwd=ROOT,
                         capture_output=True, text=True).stdout.count("::")
    assert doc["run"]["tests"] == doc["run"]["passed"] == ids > 0 and doc["run"]["exit_code"] == 0
    assert doc["run"]["commit"] == subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                                                  text=True).stdout.strip()
    assert [(f["file"], f["tests"]) for f in doc["files"]] == [("tests/test_markdown.py", ids)]
    [then] = doc["subsets"]
    assert (then["tests_then"], then["here"], then["added"], then["gone"]) == (ids, ids, 0, [])
    assert then["cpu_s"] == round(sum(t["cpu_s"] for t in doc["tests"]), 1) == doc["run"]["tests_cpu_s"]
    assert doc["run"]["cpu_s"] >= doc["run"]["tests_cpu_s"]        # the whole run holds its tests
    md = (tmp_path / "suite.md").read_text()
    assert tables.suite(doc) in md and "tests/test_markdown.py" in md


def test_failures_are_counted_and_end_in_exit_1(tmp_path):
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "test_two.py").write_text("import pytest\n\ndef test_a():\n    pass\n\n"
                                                "@pytest.mark.slow\ndef test_b():\n    assert 0\n")
    r = CliRunner().invoke(suite.main, ["-o", str(tmp_path / "out"), "--workers", "0", "--",
                                        str(tmp_path / "t" / "test_two.py")])
    assert r.exit_code == 1, r.output
    run = json.loads((tmp_path / "out" / "suite.json").read_text())["run"]
    assert (run["tests"], run["passed"], run["failed"], run["slow_tests"]) == (2, 1, 1, 1)
    assert [t.rsplit("::", 1)[1] for t in run["failed_tests"]] == ["test_b"]
    assert "test_two.py::test_b`" in (tmp_path / "out" / "suite.md").read_text()
    assert "E       assert 0" in (tmp_path / "out" / "pytest.log").read_text()   # what the failure said


def test_the_summary_line_read():
    said = "....\nFAILED x.py::t - AssertionError\n3 failed, 1375 passed, 2 skipped, 1 xfailed, 1 error in 258.64s"
    assert suite.outcome(said) == {"passed": 1375, "failed": 3, "skipped": 2, "xfailed": 1, "xpassed": 0, "errors": 1}


def test_the_command_is_make_tests():
    """The bench runs the Makefile's test recipe (its cache plugin off: nothing of one run is kept for the next)."""
    recipe = re.search(r"^test:.*\n\t\$\(BIN\)/python -m pytest (.*)$", (ROOT / "Makefile").read_text(), re.M)[1]
    command = suite.pytest_command("auto", ())
    assert command[:3] == [sys.executable, "-m", "pytest"] and command[4:6] == ["-p", "no:cacheprovider"]
    assert command[3:4] + command[6:] == recipe.replace("$(TEST_WORKERS)", "auto").split()
