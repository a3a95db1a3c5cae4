"""Typed access to a mission file's YAML mappings: every error names the file and the dotted key.

Why a module of its own: the mission parser (``mission.spec``) and the blocks it delegates
(``adaptive:`` in ``mission.adaptive.config``) read their keys the same way, with the same one-line
errors.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import yaml

from mission.errors import InputError
from mission.files import read_text


class SpecReader:
    """Typed access to a YAML mapping with dotted key paths in every error."""

    def __init__(self, data: Any, src: str, key: str = "") -> None:
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise InputError(
                f"expected a mapping, got {type(data).__name__}", source=src, field=key or None
            )
        self.d, self.src, self.key, self.used = data, src, key, set()

    def k(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def err(self, name: str, msg: str) -> InputError:
        return InputError(msg, source=self.src, field=self.k(name))

    def raw(self, name: str, default: Any = None) -> Any:
        self.used.add(name)
        return self.d.get(name, default)

    def has(self, name: str) -> bool:
        return name in self.d and self.d[name] is not None

    def num(
        self,
        name: str,
        default: float,
        lo: float | None = None,
        hi: float | None = None,
        strict_lo: bool = False,
    ) -> float:
        v = self.raw(name, default)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.err(name, f"expected a number, got {v!r}")
        if lo is not None and (v <= lo if strict_lo else v < lo):
            raise self.err(name, f"must be {'>' if strict_lo else '>='} {lo}, got {v}")
        if hi is not None and v > hi:
            raise self.err(name, f"must be <= {hi}, got {v}")
        return float(v)

    def int_(self, name: str, default: int, lo: int | None = None, hi: int | None = None) -> int:
        v = self.raw(name, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.err(name, f"expected an integer, got {v!r}")
        if lo is not None and v < lo:
            raise self.err(name, f"must be >= {lo}, got {v}")
        if hi is not None and v > hi:
            raise self.err(name, f"must be <= {hi}, got {v}")
        return v

    def str_(
        self, name: str, default: str | None, choices: tuple[str, ...] | None = None
    ) -> str | None:
        v = self.raw(name, default)
        if v is None and default is None:
            return None
        if not isinstance(v, str):
            raise self.err(name, f"expected a string, got {v!r}")
        if choices and v not in choices:
            raise self.err(name, f"expected one of {', '.join(choices)}, got '{v}'")
        return v

    def sub(self, name: str) -> SpecReader:
        return SpecReader(self.raw(name), self.src, self.k(name))

    def done(self) -> None:
        extra = [k for k in self.d if k not in self.used]
        if extra:
            raise self.err(
                str(extra[0]), "unknown key (see the schema at the top of missions/spiral.yaml)"
            )


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
