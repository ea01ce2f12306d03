"""Kill test (issue 14): 20 SIGKILLs and 20 SIGTERMs at random times during a small bake and a small
render, each over a valid previous output. After each kill it counts debris (hidden `.NAME.tmp-PID` /
`.NAME.old-PID` siblings) and checks that a valid bundle / output folder is still at -o; the next run
must remove a SIGKILL's debris (a SIGTERM must leave none). Writes OUT/kill-test.json and prints a table.

    python tools/kill_test.py -o out/kill-test [--kills 20] [--seed N]
"""
from __future__ import annotations

import argparse
import json
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

BIN = Path(sys.executable).parent
SCENE = """
[render]
resolution = [32, 32]
repeats = 3
warmup = 0
shadow_map = 256
[camera]
orbit = { count = 2 }
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.5, 0.1] }, billboards = { resolution = 128, variants = ["greedy-improved+coarse"] } }
"""


def debris(target: Path) -> list[str]:
    return sorted(p.name for p in target.parent.iterdir() if p.name.startswith(f".{target.name}."))


def bundle_ok(path: Path) -> bool:
    from vdmbake.bundle.directory import Bundle
    from vdmbake.errors import InputError
    from vdmbake.bundle.parts import KINDS

    try:
        b = Bundle(path)
        for rel, meta in b.manifest["parts"].items():
            b.read(rel, KINDS[meta["kind"]])
        return True
    except InputError:
        return False


def output_ok(path: Path) -> bool:
    try:
        return bool(json.loads((path / "report.json").read_text())["rows"])
    except (OSError, ValueError, KeyError):
        return False


def run(cmd) -> tuple[int, float]:
    t0 = time.perf_counter()
    rc = subprocess.run(cmd, capture_output=True).returncode
    return rc, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", type=Path, default=Path("out/kill-test"))
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--seed", type=int, default=int(time.time()))
    a = ap.parse_args()
    rng = random.Random(a.seed)
    shutil.rmtree(a.out, ignore_errors=True)
    a.out.mkdir(parents=True)
    scene, bundle, output = a.out / "scene.toml", a.out / "k.bundle", a.out / "render"
    scene.write_text(SCENE)
    bake_cmd = [str(BIN / "vdmbake"), str(scene), "-o", str(bundle), "--force"]
    render_cmd = [str(BIN / "vdmrender"), str(bundle), "-o", str(output), "--no-flip"]
    rc_b, t_bake = run(bake_cmd)
    rc_r, t_render = run(render_cmd)
    assert rc_b == 0 and rc_r == 0, (rc_b, rc_r)
    results = []
    for tool, cmd, target, ok, duration in (("vdmbake", bake_cmd, bundle, bundle_ok, t_bake),
                                            ("vdmrender", render_cmd, output, output_ok, t_render)):
        for sig in (signal.SIGKILL, signal.SIGTERM):
            row = {"tool": tool, "signal": sig.name, "kills": a.kills, "exit_codes": {}, "debris_after_kill": 0,
                   "debris_after_next_run": 0, "lost": 0, "median_run_s": round(duration, 2)}
            for _ in range(a.kills):
                p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                time.sleep(rng.uniform(0, duration))
                p.send_signal(sig)
                rc = p.wait()
                row["exit_codes"][str(rc)] = row["exit_codes"].get(str(rc), 0) + 1
                row["debris_after_kill"] += len(debris(target))
                if not ok(target):
                    row["lost"] += 1
                # the next run (not killed) must clean up what the kill left, and leave a valid output
                assert run(cmd)[0] == 0
                row["debris_after_next_run"] += len(debris(target))
                if not ok(target):
                    row["lost"] += 1
            results.append(row)
    (a.out / "kill-test.json").write_text(json.dumps({"seed": a.seed, "rows": results}, indent=1) + "\n")
    print(f"seed {a.seed}; bake {t_bake:.2f} s, render {t_render:.2f} s (kill times uniform in [0, that])")
    print("| tool | signal | kills | exit codes | debris after kill | debris after next run | outputs lost |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        print(f"| {r['tool']} | {r['signal']} | {r['kills']} | {r['exit_codes']} | {r['debris_after_kill']} | "
              f"{r['debris_after_next_run']} | {r['lost']} |")


if __name__ == "__main__":
    main()
