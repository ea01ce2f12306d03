"""Regression gating against a previous run's report.json (`vdmrender --baseline OLD/report.json`).

Per object and variant: the change in mean ΔLuv, p95 ΔLuv and FLIP (new minus old), the time
ratio (new median over old median) and every cost counter that changed. Thresholds in the style of
OpenImageIO's idiff (`-fail`, `-failpercent`): an absolute error increase, and a slowdown ratio that
fails the run (exit 1) only where the slowdown also exceeds the two runs' combined spread (each row's
within-camera interquartile range): the timing statistic's rule for rows not timed side by side
(vdmrender.deciding.pricing.slower, the allowed slowdown in place of its EQUAL), so two runs of the same bundle
pass under noise. Times are compared only between reports of the same device and time source (GPU timer
queries) unless asked; counters count work, not time, so any change is reported. Pure data in, data out: no
GL, no rendering.

The earlier report is input like any other: load() reads it through the regular-file guard and checks
every key compare() uses against a schema before the run renders anything, so a report that is damaged,
hand-edited or hostile ends the run at once with one message naming the row and key, never with a
traceback after the whole render.
"""
from __future__ import annotations

import json
from pathlib import Path

from vdmbake.errors import InputError, escaped
from vdmbake.formats.safeio import read_regular
from vdmbake.schema import REQUIRED, Integer, Invalid, Number, Reader, Text, Type, Vector

from . import pricing

MAX_BYTES = 64 << 20     # a report of 1000 variants x 100 cameras is about 30 MB
COUNT = Integer(0, 2**63 - 1)
NAME = Text("1-200 printable characters", r"[^\x00-\x1f\x7f]{1,200}")
TIME, VALUE = Number(0.0, 1e300), Number(-1e300, 1e300)   # finite, and their differences too
# Timed renders per camera below which --max-slowdown is refused: its noise is each row's spread_ms, an
# interquartile range over a camera's renders, which one render makes 0 and two or three make from the
# extremes (repeats = 1 flagged 33 of 69 unchanged rows as slower, issue 32).
MIN_REPEATS = 4


class Counts(Type):
    """A row's cost counters: {name: count}."""
    text = "a table of counter names (printable, 1-64 characters) to integers in [0, 2^63)"

    def parse(self, raw):
        if not isinstance(raw, dict) or not all(0 < len(k) <= 64 and k.isprintable() for k in raw):
            raise Invalid
        return {k: COUNT.parse(v) for k, v in raw.items()}


class Filtering(Type):
    """What a report's errors are against (report.json's `filtering`)."""
    text = "a table with reference_spp (an integer in [1, 65536]) and antialias (a mode name)"

    def parse(self, raw):
        if not isinstance(raw, dict):
            raise Invalid
        return {"reference_spp": Integer(1, 2**16).parse(raw.get("reference_spp")),
                "antialias": NAME.parse(raw.get("antialias"))}


POINT = {"reference_spp": 1, "antialias": "none"}   # a report without `filtering` (an older vdmrender)

# The keys of a baseline report that compare() reads: (type, default where absent or null).
TOP = {"time": (NAME, None), "device": (NAME, None), "resolution": (Vector(2, 1, 2**31 - 1, integer=True), None),
       "filtering": (Filtering(), POINT)}
ROW = {"object": (NAME, REQUIRED), "label": (NAME, REQUIRED), "median_ms": (TIME, REQUIRED), "spread_ms": (TIME, None),
       "mean_dluv": (VALUE, None), "p95_dluv": (VALUE, None), "flip_mean": (VALUE, None), "counters": (Counts(), None)}


def load(path: Path) -> dict:
    """A previous run's report, read and checked before any rendering: a regular file of at most MAX_BYTES
    (never a FIFO or device), JSON the parser reads without running out of stack, and every key compare()
    reads of its type in TOP and ROW (finite numbers, integers within int64). Returns just those keys; an
    error names the row and the key."""
    shown = escaped(str(path))
    try:
        data = read_regular(Path(path), "--baseline report", limit=MAX_BYTES)
    except FileNotFoundError:
        raise InputError(f"--baseline {shown}: file not found; give the report.json of an earlier vdmrender "
                         "run.") from None
    try:
        report = json.loads(data)
    except RecursionError:     # the parser's own bound, about 1000 levels (a report nests 5 deep)
        raise InputError(f"--baseline {shown}: JSON nested more than a report's few levels; not a vdmrender "
                         "report.json.") from None
    except ValueError as e:
        raise InputError(f"--baseline {shown}: not a readable JSON report ({e}).") from None
    top = Reader(report, "", f"--baseline {shown}: not a vdmrender report.json")
    rows = top.data.get("rows")
    if not isinstance(rows, list):
        top.fail("rows", rows, "a list of tables, one per object and variant")
    old = top.values(TOP)
    old["rows"] = [Reader(r, f"rows[{i}]", top.origin).values(ROW) for i, r in enumerate(rows)]
    budget = top.data.get("budget")                      # absent in a report of another tool: not judged
    old["repeats"] = Reader(budget, "budget", top.origin).value("repeats", COUNT, None) \
        if isinstance(budget, dict) else None
    return {**old, "resolution": old["resolution"] and list(old["resolution"]), "path": shown}


def check_spread(old: dict, repeats: int) -> None:
    """Refuse --max-slowdown where this run (`repeats` timed renders per camera) or the baseline `old` (its
    budget's) times fewer than MIN_REPEATS renders per camera: no spread to tell a slowdown from noise by."""
    for who, n, fix in (("this run", repeats, f"--repeats {MIN_REPEATS} (or render.repeats in the scene)"),
                        (f"the baseline {old['path']}", old.get("repeats"), f"a baseline rendered with --repeats "
                                                                            f"{MIN_REPEATS} or more")):
        if n is not None and n < MIN_REPEATS:
            raise InputError(f"--max-slowdown needs at least {MIN_REPEATS} timed renders per frame in both runs to "
                             f"measure the spread a slowdown is judged against, and {who} times {n}; give {fix}, "
                             "or leave --max-slowdown out.")


def _diff(new, old):
    return None if new is None or old is None else round(new - old, 4)


def times_comparable(old: dict, new: dict, across_devices: bool = False) -> str | None:
    """None if the two reports' times may be compared, else why not."""
    if old.get("time") != new.get("time"):
        return (f"times not compared: the baseline's are {old.get('time') or 'wall times (an older vdmrender)'}, "
                f"this run's {new.get('time')}")
    if old.get("device") != new.get("device") and not across_devices:
        return (f"times not compared: the baseline ran on {old.get('device')!r}, this run on {new.get('device')!r} "
                "(--compare-devices compares them anyway)")
    return None


def errors_comparable(old: dict, filtering: dict) -> str | None:
    """None if the baseline's errors were measured as this run's are (the reference's samples per pixel, the
    frames' anti-aliasing), else why not: against a filtered reference every error moves."""
    was, now = old.get("filtering") or POINT, {k: filtering[k] for k in POINT}
    if was == now:
        return None
    return (f"errors not compared: the baseline's are against a {was['reference_spp']}-spp reference with frames "
            f"anti-aliased {was['antialias']}, this run's against {now['reference_spp']} spp with {now['antialias']} "
            "(give the baseline's --reference-spp and --antialias to compare)")


def _counters_changed(o: dict | None, n: dict | None) -> dict:
    """{counter: [old, new]} for every counter present in either row that differs."""
    a, b = (o or {}).get("counters") or {}, (n or {}).get("counters") or {}
    if not a or not b:
        return {}
    return {k: [a.get(k), b.get(k)] for k in dict.fromkeys([*a, *b]) if a.get(k) != b.get(k)}


def compare(old: dict, new: dict, max_error_increase: float | None, max_slowdown: float | None,
            across_devices: bool = False) -> dict:
    """The baseline block of the new report: one change row per object and variant in either run,
    and which thresholds each exceeds. status: `compared`; `new` (no old row); `missing` (an old
    row the new run lacks: not a failure, the run may have been filtered with -t)."""
    why_not = times_comparable(old, new, across_devices)
    errors_not = errors_comparable(old, new.get("filtering") or POINT)
    old_rows = {(r["object"], r["label"]): r for r in old["rows"]}
    new_rows = {(r["object"], r["label"]): r for r in new["rows"]}
    changes = []
    for key in [*new_rows, *(k for k in old_rows if k not in new_rows)]:
        o, n = old_rows.get(key), new_rows.get(key)
        get = lambda r, k: None if r is None else r.get(k)  # noqa: E731
        timed = why_not is None and o and n and o["median_ms"] and n["median_ms"]
        ratio = round(n["median_ms"] / o["median_ms"], 4) if timed else None
        noise = round(pricing.noise_ms(o, n), 4) if timed else None
        c = {"object": key[0], "label": key[1], "status": "compared" if o and n else ("new" if n else "missing"),
             "old_mean_dluv": get(o, "mean_dluv"), "new_mean_dluv": get(n, "mean_dluv"),
             "d_mean_dluv": _diff(get(n, "mean_dluv"), get(o, "mean_dluv")),
             "old_p95_dluv": get(o, "p95_dluv"), "new_p95_dluv": get(n, "p95_dluv"),
             "d_p95_dluv": _diff(get(n, "p95_dluv"), get(o, "p95_dluv")),
             "old_flip": get(o, "flip_mean"), "new_flip": get(n, "flip_mean"),
             "d_flip": _diff(get(n, "flip_mean"), get(o, "flip_mean")),
             "old_ms": get(o, "median_ms"), "new_ms": get(n, "median_ms"), "time_ratio": ratio, "noise_ms": noise,
             "counters_changed": _counters_changed(o, n)}
        if errors_not:   # measured against another reference or other frames: no change to speak of
            c.update(d_mean_dluv=None, d_p95_dluv=None, d_flip=None)
        exceeds = []
        if max_error_increase is not None and c["d_mean_dluv"] is not None and c["d_mean_dluv"] > max_error_increase:
            exceeds.append("error")
        if max_slowdown is not None and timed and pricing.slower(o, n, max_slowdown - 1):
            exceeds.append("time")
        changes.append({**c, "exceeds": exceeds})
    notes = [f"baseline {k} {old.get(k)!r} differs from this run's {new.get(k)!r}"
             for k in ("device", "resolution") if old.get(k) != new.get(k)] + [x for x in (why_not, errors_not) if x]
    notes += [f"{c['object']}: {c['label']}: counters changed: "
              + ", ".join(f"{k} {a} -> {b}" for k, (a, b) in c["counters_changed"].items())
              for c in changes if c["counters_changed"]]
    return {"thresholds": {"max_error_increase": max_error_increase, "max_slowdown": max_slowdown},
            "notes": notes, "rows": changes, "failed": [f"{c['object']}: {c['label']}" for c in changes if c["exceeds"]]}
