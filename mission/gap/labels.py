"""Short flight labels: file stems without the prefix they all share (``288_loc_1``, not
``results_useful_ori_exp_288_loc_1``), so that tables fit 80 columns and flights stay
recognisable."""

from __future__ import annotations

import re
from collections.abc import Sequence

_SEP = re.compile(r"(?<=[_\-. ])")


def short_labels(names: Sequence[str], max_len: int = 16) -> list[str]:
    """Drop the leading tokens (split after ``_ - . space``) every name shares; keep at least one
    token before a purely numeric rest (``loc_1``, not ``1``); cut to ``max_len`` (keeping the end);
    unique or unchanged."""
    names = [str(n) for n in names]
    if len(names) < 2:
        return [n[-max_len:] for n in names]
    toks = [_SEP.split(n) for n in names]
    k = 0
    while all(len(t) > k + 1 for t in toks) and len({t[k] for t in toks}) == 1:
        k += 1
    if k and any(re.fullmatch(r"[\d_\-. ]*", "".join(t[k:])) for t in toks):
        k -= 1
    out = ["".join(t[k:])[-max_len:] for t in toks]
    return out if len(set(out)) == len(out) else names
