"""Strict JSON out of numpy-laden results: non-finite numbers become ``null`` (JSON has no NaN or
Infinity, and strict readers such as ``jq`` or JavaScript's ``JSON.parse`` refuse Python's ``NaN`` /
``Infinity``)."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def finite_or_none(o: Any) -> Any:
    """``o`` with numpy arrays and scalars as Python lists and numbers, and every non-finite float
    as None."""
    if isinstance(o, dict):
        return {k: finite_or_none(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [finite_or_none(v) for v in o]
    if isinstance(o, np.ndarray):
        return finite_or_none(o.tolist())
    if isinstance(o, np.generic):
        o = o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def dumps(o: Any, **kw: Any) -> str:
    """``json.dumps`` that always writes strict JSON (see ``finite_or_none``); other objects by
    ``str``."""
    return json.dumps(finite_or_none(o), allow_nan=False, default=str, **kw)
