"""The scene's typed schema: value types with their ranges, dataclass fields that carry their type
and documentation, one reader that validates a TOML table against such a dataclass, and the
markdown reference generated from the same declarations (docs/scenes.md and --help).

A dataclass is its own schema: each field is declared with `setting(default, TYPE, "doc")` and
`read(cls, table)` builds an instance, naming the file, the key, the bad value and what is
allowed in every error. `dump` writes an instance back as plain data that `read` accepts. A
setting declared with `flag=` is also a command-line option that overrides it (`overridable`):
its value is read from the option's text by the same type (`Type.from_text`), so a file and a
flag accept and refuse the same values.
"""
from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Callable

from .errors import InputError, cut, escaped


REQUIRED = dataclasses.MISSING


def show(value) -> str:
    """A value as an error message shows it: its repr, one line, at most about 200 characters."""
    return cut(repr(value))


class Invalid(Exception):
    """A value a type does not accept (the reader turns it into an InputError naming the key)."""


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _finite(x) -> bool:
    try:
        return math.isfinite(x)
    except OverflowError:        # an integer literal beyond float's range
        return False


class Type:
    """A value type: parse(raw) -> value or raise Invalid; dump(value) -> plain data; text says what
    is allowed (error messages and docs); from_text(text) -> raw: a command-line option's text as the
    plain data `parse` reads (a string, unless the type reads something else)."""
    text = "any value"

    def parse(self, raw):
        return raw

    def from_text(self, text: str):
        return text

    def dump(self, value):
        return value


class Custom(Type):
    """A value the caller reads itself; `text` documents it."""

    def __init__(self, text: str):
        self.text = text


class Integer(Type):
    def __init__(self, lo: int, hi: int):
        self.lo, self.hi = lo, hi
        self.text = f"an integer in [{lo}, {hi}]"

    def parse(self, raw):
        if isinstance(raw, bool) or not isinstance(raw, int) or not self.lo <= raw <= self.hi:
            raise Invalid
        return int(raw)

    def from_text(self, text: str):
        return _integer_text(text)


class Square(Integer):
    """A perfect square N x N in [1, hi] (samples on a grid of N by N)."""

    def __init__(self, hi: int):
        super().__init__(1, hi)
        self.text = f"a square number in [1, {hi}] (1, 4, 9, 16, ...: N x N)"

    def parse(self, raw):
        v = super().parse(raw)
        if math.isqrt(v) ** 2 != v:
            raise Invalid
        return v


class Number(Type):
    def __init__(self, lo: float = -math.inf, hi: float = math.inf, open_lo: bool = False):
        self.lo, self.hi, self.open_lo = lo, hi, open_lo
        self.text = f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}]"

    def parse(self, raw):
        if not _number(raw) or not _finite(raw):
            raise Invalid
        v = float(raw)
        if not (self.lo < v if self.open_lo else self.lo <= v) or not v <= self.hi:
            raise Invalid
        return v

    def from_text(self, text: str):
        return _number_text(text)


class Boolean(Type):
    text = "true or false"

    def parse(self, raw):
        if not isinstance(raw, bool):
            raise Invalid
        return raw


class Choice(Type):
    def __init__(self, *values):
        self.values = values
        self.text = "one of " + ", ".join(repr(v) for v in values)

    def parse(self, raw):
        if not isinstance(raw, str) or raw not in self.values:
            raise Invalid
        return raw


class Text(Type):
    """A non-empty string, optionally matching a pattern."""

    def __init__(self, text: str = "a non-empty string", pattern: str | None = None):
        self.text, self.pattern = text, pattern and re.compile(pattern)

    def parse(self, raw):
        if not isinstance(raw, str) or not raw or (self.pattern and not self.pattern.fullmatch(raw)):
            raise Invalid
        return raw


class Vector(Type):
    """n finite numbers in [lo, hi] (integers if `integer`), as a tuple; `scalar` also accepts one
    number for all n. On a command line the numbers are separated by `sep` (512x512)."""

    def __init__(self, n: int, lo: float = -math.inf, hi: float = math.inf, integer: bool = False,
                 nonzero: bool = False, scalar: bool = False, sep: str = ","):
        self.n, self.lo, self.hi, self.integer, self.nonzero, self.scalar = n, lo, hi, integer, nonzero, scalar
        self.sep = sep
        kind = "integers" if integer else "finite numbers"
        bounds = f" in [{lo:g}, {hi:g}]" if math.isfinite(lo) or math.isfinite(hi) else ""
        self.text = (f"a list of {n} {kind}{bounds}" + (", not all zero" if nonzero else "")
                     + (" (or one number for all)" if scalar else ""))

    def parse(self, raw):
        if self.scalar and _number(raw):
            raw = [raw] * self.n
        if not isinstance(raw, (list, tuple)) or len(raw) != self.n:
            raise Invalid
        ok = int if self.integer else (int, float)
        if not all(isinstance(x, ok) and not isinstance(x, bool) and _finite(x) and self.lo <= x <= self.hi
                   for x in raw):
            raise Invalid
        if self.nonzero and not any(raw):
            raise Invalid
        return tuple(int(x) if self.integer else float(x) for x in raw)

    def from_text(self, text: str):
        return [(_integer_text if self.integer else _number_text)(x) for x in text.split(self.sep)]

    def dump(self, value):
        return list(value)


def unit(v) -> tuple[float, ...]:
    """v / |v|, scaled by its largest component first, so that tiny vectors (1e-200) normalise
    instead of underflowing; a vector already of unit length (to rounding) is kept as it is."""
    if abs(math.fsum(x * x for x in v) - 1.0) < 1e-15:
        return tuple(float(x) for x in v)
    m = max(abs(x) for x in v)
    s = [x / m for x in v]
    n = math.sqrt(sum(x * x for x in s))
    return tuple(x / n for x in s)


class Direction(Vector):
    """A non-zero 3-vector (the dataclass holding it normalises it with `unit`)."""

    def __init__(self):
        super().__init__(3, nonzero=True)
        self.text = "a list of 3 finite numbers, not all zero"


class Either(Type):
    """The first of several types that accepts the value."""

    def __init__(self, *types: Type):
        self.types = types
        self.text = " or ".join(t.text for t in types)

    def parse(self, raw):
        for t in self.types:
            try:
                return t.parse(raw)
            except Invalid:
                pass
        raise Invalid


class Parsed(Type):
    """A string turned into a value by `make(match)` when it fully matches `pattern`; str(value)
    gives the string back (labels, manifests)."""

    def __init__(self, pattern: str, make: Callable[[re.Match], Any], text: str):
        self.pattern, self.make, self.text = re.compile(pattern), make, text

    def parse(self, raw):
        m = self.pattern.fullmatch(raw) if isinstance(raw, str) else None
        if m is None:
            raise Invalid
        return self.make(m)

    def dump(self, value):
        return str(value)


class ListOf(Type):
    """A non-empty list of distinct values of one type, as a tuple (a technique's knob values)."""

    def __init__(self, item: Type):
        self.item = item
        self.text = f"a non-empty list of distinct values, each {item.text}"

    def parse(self, raw):
        if not isinstance(raw, list) or not raw:
            raise Invalid
        values = tuple(self.item.parse(x) for x in raw)
        if len({_key(self.item.dump(v)) for v in values}) != len(values):
            raise Invalid
        return values

    def from_text(self, text: str):
        """Values separated by commas (512,128,32)."""
        return [self.item.from_text(x) for x in text.split(",")]

    def dump(self, value):
        return [self.item.dump(v) for v in value]


def _integer_text(text: str) -> int:
    if not re.fullmatch(r"\s*[+-]?\d+\s*", text):
        raise Invalid
    return int(text)


def _number_text(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise Invalid from None


def _key(v):
    """Equal knob values (1 and 1.0) are duplicates."""
    return float(v) if _number(v) else str(v)


class Table(Type):
    """A nested table read into the dataclass `cls`."""

    def __init__(self, cls):
        self.cls = cls
        self.text = f"a table ({', '.join(f.name for f in dataclasses.fields(cls))})"


class Tables(Type):
    """An array of tables, each read into `cls`."""

    def __init__(self, cls):
        self.cls = cls
        self.text = f"an array of tables ({', '.join(f.name for f in dataclasses.fields(cls))})"

    def dump(self, value):
        return [dump(v) for v in value]


def setting(default, type_: Type, doc: str, *, knob: str | None = None, flag: str | None = None):
    """A dataclass field that is a scene setting. knob: on a technique's options, marks the list
    swept into an error-against-time curve, and names one value of it in reports ("ratio"). flag:
    the renderer's option `--NAME` (NAME the field's, with hyphens) overrides the setting; `flag` is
    how its value is written there (its metavar: WIDTHxHEIGHT)."""
    kwargs = {"default": default} if default is not REQUIRED else {}
    return dataclasses.field(**kwargs, metadata={"type": type_, "doc": doc, "knob": knob, "flag": flag})


def settings(cls) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(cls) if "type" in f.metadata]


def flag_name(f: dataclasses.Field) -> str:
    """The command-line option overriding the setting `f` (declared with `flag=`)."""
    return "--" + f.name.replace("_", "-")


def overridable(cls, prefix: str = "") -> list[tuple[str, dataclasses.Field]]:
    """(key, field) of every setting declared with `flag=` in `cls` and its nested tables, the key spelled
    as in docs/scenes.md (render.sweep.sizes)."""
    out = []
    for f in settings(cls):
        if f.metadata["flag"]:
            out.append((prefix + f.name, f))
        if isinstance(f.metadata["type"], Table):
            out += overridable(f.metadata["type"].cls, f"{prefix}{f.name}.")
    return out


class Reader:
    """A table being read: typed values by key, unknown keys refused with every allowed key listed."""

    def __init__(self, data, where: str, origin: str):
        if not isinstance(data, dict):
            raise InputError(f"{origin}: [{where or 'top level'}] must be a table, got {show(data)}.")
        self.data, self.where, self.origin = data, where, origin

    def key(self, key: str) -> str:
        key = escaped(str(key))
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str, value, allowed: str):
        raise InputError(f"{self.origin}: key '{self.key(key)}' has value {show(value)}; allowed: {allowed}.")

    def has(self, key: str) -> bool:
        return self.data.get(key) is not None   # JSON null (a manifest's "no value") counts as absent

    def value(self, key: str, type_: Type, default=REQUIRED):
        if not self.has(key):
            if default is REQUIRED:
                self.fail(key, None, type_.text)
            return default
        raw = self.data[key]
        if isinstance(type_, Table):
            return read(type_.cls, self.table(key))
        if isinstance(type_, Tables):
            if not isinstance(raw, list):
                self.fail(key, raw, type_.text)
            return tuple(read(type_.cls, Reader(x, f"{self.key(key)}[{i}]", self.origin)) for i, x in enumerate(raw))
        try:
            return type_.parse(raw)
        except Invalid:
            self.fail(key, raw, type_.text)

    def values(self, declared: dict) -> dict:
        """Every key of `declared` ({key: (type, default)}: a file's declared keys) read as `value` reads it."""
        return {key: self.value(key, type_, default) for key, (type_, default) in declared.items()}

    def table(self, key: str) -> "Reader":
        return Reader(self.data.get(key) if self.has(key) else {}, self.key(key), self.origin)

    def only(self, allowed) -> None:
        """Refuse keys outside `allowed`, listing all of them."""
        unknown = [k for k in self.data if k not in allowed]
        if unknown:
            raise InputError(f"{self.origin}: unknown key '{self.key(unknown[0])}' in [{self.where or 'top level'}]; "
                             f"allowed keys there: {', '.join(allowed) or 'none'}.")


def read(cls, t: Reader, **given):
    """An instance of dataclass `cls` from the table: every setting field by its type (its default
    where absent); `given` supplies fields the caller read itself. Unknown keys are refused."""
    values = dict(given)
    for f in settings(cls):
        if f.name not in values:
            default = f.default if f.default is not dataclasses.MISSING else REQUIRED
            values[f.name] = t.value(f.name, f.metadata["type"], default)
    t.only([f.name for f in settings(cls)])
    return cls(**values)


def dump(obj) -> dict:
    """A dataclass instance as plain data (lists, strings, numbers) that `read` accepts again;
    None-valued and empty fields are left out."""
    out = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if v is None or v == ():
            continue
        t = f.metadata.get("type")
        if dataclasses.is_dataclass(v):
            out[f.name] = dump(v)
        elif isinstance(t, Type) and not isinstance(t, Custom):
            out[f.name] = t.dump(v)
        elif isinstance(v, dict):
            out[f.name] = {k: dump(x) if dataclasses.is_dataclass(x) else x for k, x in v.items()}
        elif isinstance(v, tuple):
            out[f.name] = [dump(x) if dataclasses.is_dataclass(x) else x for x in v]
        else:
            out[f.name] = v
    return out


def knob(cls) -> dataclasses.Field | None:
    """The options field marked as the technique's knob, if any."""
    return next((f for f in settings(cls) if f.metadata["knob"]), None)


def default_text(f: dataclasses.Field) -> str:
    """A setting's default as docs/scenes.md and --help give it: `5`, `"none"`, none, required, its defaults."""
    t = f.metadata["type"]
    if f.default is dataclasses.MISSING:
        return "required"
    if f.default is None or f.default == ():
        return "none"
    if isinstance(t, (Table, Tables, Custom)):
        return "its defaults"
    return f"`{_toml(t.dump(f.default))}`"


def markdown(cls, prefix: str = "") -> list[str]:
    """Markdown table rows `| key | allowed | default | meaning |` for the settings of `cls`; a setting with a
    command-line option names it."""
    rows = []
    for f in settings(cls):
        also = f"; `vdmrender {flag_name(f)}`" if f.metadata["flag"] else ""
        rows.append(f"| `{prefix}{f.name}` | {f.metadata['type'].text} | {default_text(f)} | {f.metadata['doc']}{also} |")
    return rows


def _toml(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + " }"
    return str(v)


def shortest(value: float) -> str:
    """The fewest significant digits that read back as `value` (0.5, 0.5000001, 1): a knob value in a
    label or a part's file name."""
    return next(s for s in (f"{value:.{p}g}" for p in range(1, 18)) if float(s) == value)


@dataclasses.dataclass(frozen=True)
class Technique:
    """A rendering technique, declared once in its module of vdmbake/techniques/: the objects it
    draws, its settings (a dataclass of `setting` fields, its knob marked), and the bake step that
    writes the bundle parts it needs. Its renderer is vdmrender/techniques/NAME.py."""
    name: str
    summary: str                      # what it draws, one sentence (docs/scenes.md, --help)
    kinds: tuple[str, ...]            # object kinds: "surface" (mesh file, primitive), "quadrics"
    options: type                     # dataclass of its settings
    mesostructure: bool = False       # draws the object's [objects.mesostructure] (which it then needs)
    bake: Callable | None = None      # bake(job) -> its manifest entry (vdmbake.bake.Job)
    combine: Callable | None = None   # options -> variant values (with .plain(): the report's spelling), where
                                      # more settings than the knob make a variant
    reads: Callable | None = None     # (its manifest entry, a variant's value, the object) -> {part path: part
                                      # kind} the variant's renderer reads; with `bake`. The bundle checks these
                                      # before rendering (vdmbake.bundle.manifest); any lookup error is a bad entry
    triangles: str | None = None      # draws the object as triangles: "mesh" (its mesh or a simplification, which a
                                      # glTF carries as it is), "made" (made at load: displaced, tessellated); a
                                      # level of detail ranked by its faces (vdmrender.deciding.lod)

    @property
    def knob(self) -> dataclasses.Field | None:
        return knob(self.options)

    def values(self, options) -> tuple:
        """The variants' values in scene order: the knob's values, or what `combine` makes of the
        options (one variant, None, without a knob)."""
        if self.combine:
            return tuple(self.combine(options))
        k = self.knob
        return getattr(options, k.name) if k else (None,)

    def label(self, value) -> str:
        """A variant's name in reports: technique@value (technique alone without a knob); a number as
        `shortest` spells it, so two distinct values of a knob (ListOf refuses equal ones) never share a
        label or a folder."""
        if value is None:
            return self.name
        return f"{self.name}@{shortest(value) if isinstance(value, float) else value}"
