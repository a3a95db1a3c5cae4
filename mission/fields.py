"""One validation layer for configurations, cards and metadata: typed access to a mapping whose
every refusal is a one-line ``InputError`` naming the file and the dotted field (exit code 2).

Why a module of its own: the mission file (``mission.spec``, its ``adaptive:`` block), a dataset's
configuration, a physics family's distributions, a model card and a flight log's sidecar are all
mappings read from a user's file; each reads its keys through ``Fields`` so that a bad value is
refused the same way, with the same wording, wherever it sits.  ``read_yaml`` parses a YAML file
with limits.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import yaml

from mission.errors import InputError
from mission.files import read_text

# ``default=REQUIRED``: the key must be present (and not null)
REQUIRED: Any = object()

# How ``Fields.typed`` names the JSON types it expects
TYPE_NAMES = {
    dict: "an object",
    list: "a list",
    str: "a string",
    int: "an integer",
    float: "a number",
    bool: "true/false",
}


def is_number(v: Any) -> bool:
    """A finite int or float that is not a bool."""
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


class Fields:
    """Typed access to a mapping read from ``src``; ``key`` is its dotted place in the file.

    Each accessor marks its name as read; ``done()`` refuses the keys nobody read (a typo must not
    be silently ignored).  ``hint``: what ``done()`` adds to an unknown key's error (where the
    schema is written).  A ``default`` of ``REQUIRED`` makes a key mandatory; ``None`` makes it
    optional (absent or null reads as None).  ``shape``: what a value that is not a mapping is
    told was expected."""

    hint: str | None = None

    def __init__(
        self, data: Any, src: str | None = None, key: str = "", shape: str = "a mapping"
    ) -> None:
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise InputError(
                f"expected {shape}, got {type(data).__name__}", source=src, field=key or None
            )
        self.d, self.src, self.key, self.used = data, src, key, set()

    @classmethod
    def holding(cls, value: Any, src: str | None, field: str) -> tuple[Fields, str]:
        """A reader of the one ``value`` found at dotted ``field``, and the name to read it by."""
        parent, _, name = field.rpartition(".")
        return cls({name: value}, src, parent), name

    def k(self, name: str) -> str:
        """The dotted field of ``name`` in this mapping."""
        return f"{self.key}.{name}" if self.key else name

    def err(self, name: str, msg: str) -> InputError:
        """The one-line error for ``name``: file, dotted field and ``msg``."""
        return InputError(msg, source=self.src, field=self.k(name))

    def raw(self, name: str, default: Any = None) -> Any:
        """The value as it is (``default`` when absent); ``REQUIRED`` refuses an absent key."""
        self.used.add(name)
        if default is REQUIRED and self.d.get(name) is None:
            raise self.err(name, "missing")
        return self.d.get(name, default)

    def has(self, name: str) -> bool:
        """Whether ``name`` is present and not null."""
        return name in self.d and self.d[name] is not None

    def _optional(self, name: str, default: Any) -> bool:
        """True when ``name`` is optional (``default`` None) and absent or null: read as None."""
        if default is None and not self.has(name):
            self.used.add(name)
            return True
        return False

    def num(
        self,
        name: str,
        default: Any = REQUIRED,
        lo: float | None = None,
        hi: float | None = None,
        strict_lo: bool = False,
    ) -> Any:
        """A finite number (bool is not one) in [lo, hi] (``strict_lo``: above lo)."""
        if self._optional(name, default):
            return None
        v = self.raw(name, default)
        if not is_number(v):
            raise self.err(name, f"expected a number, got {v!r}")
        if lo is not None and (v <= lo if strict_lo else v < lo):
            raise self.err(name, f"must be {'>' if strict_lo else '>='} {lo}, got {v}")
        if hi is not None and v > hi:
            raise self.err(name, f"must be <= {hi}, got {v}")
        return float(v)

    def int_(
        self, name: str, default: Any = REQUIRED, lo: int | None = None, hi: int | None = None
    ) -> Any:
        """An integer (bool is not one) in [lo, hi]."""
        if self._optional(name, default):
            return None
        v = self.raw(name, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(name, f"expected an integer, got {v!r}")
        if lo is not None and v < lo:
            raise self.err(name, f"must be >= {lo}, got {v}")
        if hi is not None and v > hi:
            raise self.err(name, f"must be <= {hi}, got {v}")
        return v

    def str_(self, name: str, default: Any = REQUIRED, choices: Iterable[str] | None = None) -> Any:
        """A string, one of ``choices`` when given."""
        if self._optional(name, default):
            return None
        v = self.raw(name, default)
        if not isinstance(v, str):
            raise self.err(name, f"expected a string, got {v!r}")
        choices = tuple(choices) if choices is not None else None
        if choices and v not in choices:
            raise self.err(name, f"expected one of {', '.join(choices)}, got '{v}'")
        return v

    def bool_(self, name: str, default: Any = REQUIRED) -> Any:
        """true or false."""
        if self._optional(name, default):
            return None
        v = self.raw(name, default)
        if not isinstance(v, bool):
            raise self.err(name, f"expected true or false, got {v!r}")
        return v

    def span(
        self,
        name: str,
        default: Any = REQUIRED,
        lo: float | None = None,
        strict_lo: bool = False,
        ordered: bool = True,
    ) -> Any:
        """Two finite numbers ``[low, high]`` (``ordered``: low <= high), each at least ``lo``
        (``strict_lo``: above it); a tuple of floats."""
        if self._optional(name, default):
            return None
        v = self.raw(name, default)
        if not (isinstance(v, list | tuple) and len(v) == 2 and all(is_number(x) for x in v)):
            raise self.err(name, f"expected [low, high], got {v!r}")
        if ordered and v[0] > v[1]:
            raise self.err(name, f"needs low <= high, got {list(v)!r}")
        if lo is not None and (min(v) <= lo if strict_lo else min(v) < lo):
            raise self.err(name, f"must be {'>' if strict_lo else '>='} {lo}, got {list(v)!r}")
        return float(v[0]), float(v[1])

    def typed(self, name: str, types: tuple[type, ...]) -> Any:
        """The value (None when absent or null) if it has one of the JSON ``types``; a float must
        be finite and bool counts only where listed."""
        v = self.raw(name)
        if v is None:
            return None
        good = isinstance(v, types) and not (isinstance(v, bool) and bool not in types)
        if good and isinstance(v, float) and not math.isfinite(v):
            good = False
        if not good:
            names = " or ".join(TYPE_NAMES[t] for t in types)
            raise self.err(name, f"expected {names}, got {type(v).__name__} {str(v)[:40]!r}")
        return v

    def sub(self, name: str, default: Any = None) -> Fields:
        """The mapping under ``name`` (absent or null: empty, unless ``default`` is REQUIRED)."""
        return type(self)(self.raw(name, default), self.src, self.k(name))

    def done(self, allowed: Iterable[str] | None = None) -> None:
        """Refuse a key that nobody read (or, given ``allowed``, that is not among them)."""
        known = self.used if allowed is None else set(allowed)
        extra = [str(k) for k in self.d if k not in known]
        if extra:
            also = f"; also {', '.join(extra[1:])}" if len(extra) > 1 else ""
            hint = f" ({self.hint})" if self.hint else ""
            raise self.err(extra[0], f"unknown key{also}{hint}")


def check_types(d: dict, types: dict[str, tuple[type, ...]], source: str | None) -> None:
    """Every dotted key of ``types`` present (not null) in ``d`` has one of its JSON types
    (``Fields.typed``); a key under a parent that is not an object is left to the parent's own
    entry."""
    for key, ok in types.items():
        head, _, tail = key.rpartition(".")
        parent: Any = d
        for part in head.split(".") if head else ():
            parent = parent.get(part) if isinstance(parent, dict) else None
        if isinstance(parent, dict):
            Fields(parent, source, head).typed(tail, ok)


def read_yaml(path: str | Path, what: str = "mission file", max_bytes: int = 1_000_000) -> Any:
    """Parse a YAML file with limits: a regular UTF-8 file of at most ``max_bytes``, no aliases (a
    "billion laughs" bomb is refused, not expanded), no duplicated key (the last one silently won),
    bounded nesting; every problem is an InputError naming the file and line."""
    text = read_text(path, what, max_bytes=max_bytes)
    src = str(path)
    try:
        return yaml.load(text, Loader=_limited_loader())  # a SafeLoader subclass
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise InputError(f"malformed YAML{where}: {problem}", source=src) from None
    except RecursionError:
        raise InputError("YAML nested too deeply", source=src) from None


@functools.cache
def _limited_loader():
    class LimitedLoader(yaml.SafeLoader):
        """``yaml.SafeLoader`` that refuses aliases and duplicated keys."""

        def compose_node(self, parent, index):
            if self.check_event(yaml.AliasEvent):
                ev = self.peek_event()
                raise yaml.composer.ComposerError(
                    None,
                    None,
                    f"alias *{ev.anchor} refused (anchors and aliases "
                    "are not accepted: write the value out)",
                    ev.start_mark,
                )
            return super().compose_node(parent, index)

        def construct_mapping(self, node, deep=False):
            if isinstance(node, yaml.MappingNode):
                seen: set = set()
                for key_node, _ in node.value:
                    key = key_node.value if isinstance(key_node, yaml.ScalarNode) else id(key_node)
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"duplicated key '{key}'", key_node.start_mark
                        )
                    seen.add(key)
            return super().construct_mapping(node, deep)

    LimitedLoader.add_constructor(
        yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, LimitedLoader.construct_mapping
    )
    return LimitedLoader
