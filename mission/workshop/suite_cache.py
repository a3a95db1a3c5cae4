"""The unseen-flight benchmark's on-disk cache: CSV logs + ``suite.json`` (truths, draws, a
fingerprint).

Why a cache: scoring many methods on the same 200 flights should not simulate them again each time;
why a fingerprint: a cache written by older simulator code was once re-used and gave figures 3-8 m
off the current code's, without a word.

    # cached CSV logs + suite.json (truths, draws)
    write_suite("/tmp/suite_unseen_2026", n=200, seed=2026)
    flights = read_suite("/tmp/suite_unseen_2026")  # same flights back (lazy: .load(i))
    flights.check_current()  # None, or a warning: cache is stale

A stale cache is never read silently: ``suite.json`` keeps a fingerprint of flight 0 as the writing
code simulated it (``flight_fingerprint``: sha256 of its quantised log columns and truth), and
``CachedSuite.check_current`` (run by ``evaluate_suite`` and so by ``rfsl evaluate --suite-dir``,
~20 ms) re-simulates flight 0 and returns a one-line warning when the fingerprint differs or is
missing (a cache from before fingerprints); the figures of such a cache are not the current code's
(an old one was 3-8 m off), so rewrite it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mission.errors import InputError
from mission.fields import REQUIRED, Fields
from mission.files import read_text
from mission.flightlog import read_flight_log, write_flight_log
from mission.physics.family import PhysicsFamily
from mission.threads import pool_context
from mission.workshop.suite import (
    BENCHMARK_SEED,
    FamilyArg,
    SuiteFlight,
    family_label,
    family_sha256,
    resolve_family,
    unseen_flight,
)

FORMAT = "rfsl-suite/1"
FINGERPRINT_SCHEME = "quantised-columns/1"
# Quantum per log column of the fingerprint: coarse enough that another machine's last-bit float
# differences do not flip it, fine enough that any change of what the simulation produces does (1e-7
# deg ~ 1 cm).
FINGERPRINT_STEPS = {
    "t_s": 1e-3,
    "lat_deg": 1e-7,
    "lon_deg": 1e-7,
    "alt_m": 1e-2,
    "rel_alt_m": 1e-2,
    "roll_deg": 1e-2,
    "pitch_deg": 1e-2,
    "yaw_deg": 1e-2,
    "rss_dbm": 1e-2,
}


def _quantised(v, step: float) -> bytes:
    q = np.nan_to_num(
        np.rint(np.asarray(v, dtype=float) / step),
        nan=-(2.0**62),
        posinf=2.0**62,
        neginf=-(2.0**62),
    )
    return q.astype(np.int64).tobytes()


def flight_fingerprint(f: SuiteFlight) -> str:
    """sha256 of a flight's log columns and truth, quantised (``FINGERPRINT_STEPS``): what the code
    simulates."""
    h = hashlib.sha256(FINGERPRINT_SCHEME.encode())
    cols = f.log.columns
    for c, step in FINGERPRINT_STEPS.items():
        h.update(f"|{c}:{len(cols[c]) if c in cols else -1}|".encode())
        if c in cols:
            h.update(_quantised(cols[c], step))
    h.update(b"|truth_xy|" + _quantised(f.truth_xy, 1e-2))
    return h.hexdigest()


def _write_one(args: tuple) -> tuple[dict, str | None]:
    out, seed, i, family, center = args
    f = unseen_flight(seed, i, family, center)
    p = Path(out) / f"flight_{i:05d}.csv"
    p.unlink(missing_ok=True)
    p.with_suffix(".json").unlink(missing_ok=True)
    write_flight_log(p, f.log.columns, f.log.meta)
    fp = flight_fingerprint(f) if i == 0 else None
    return {"file": p.name, "truth_xy": f.truth_xy.tolist(), "draw": f.draw}, fp


def write_suite(
    out_dir: str | Path,
    n: int,
    seed: int = BENCHMARK_SEED,
    family: FamilyArg = "afar",
    center: str = "afar",
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Write flights 0..n-1 as CSV logs + sidecars and ``suite.json`` (truths, draws) into
    ``out_dir``.

    With a family file the manifest keeps the family itself (``family_record``, ``family_sha256``)
    beside its path, so the cache stays checkable and rewritable when the file moves or changes."""
    if n < 1:
        raise InputError(f"need n >= 1, got {n}", field="n")
    fam = resolve_family(family)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(str(out), int(seed), i, fam, center) for i in range(n)]
    rows: list[dict] = []
    fingerprint = ""
    for k, (r, fp) in enumerate(_map(_write_one, jobs, workers)):
        rows.append(r)
        fingerprint = fp or fingerprint
        if progress:
            progress(k + 1, n)
    man = {
        "format": FORMAT,
        "suite": "unseen",
        "seed": int(seed),
        "family": family_label(fam),
        "center": center,
        "n": n,
        **_family_fields(fam, family),
        "seeding": "flight i: SeedSequence([seed, SUITE_TAG=10], spawn_key=(i,))",
        "fingerprint": {"flight": 0, "scheme": FINGERPRINT_SCHEME, "sha256": fingerprint},
        "flights": rows,
    }
    (out / "suite.json").write_text(json.dumps(man, indent=1, default=float))
    return man


def _family_fields(fam, given: FamilyArg) -> dict:
    if isinstance(fam, str):
        return {}
    return {
        "family_path": str(given) if isinstance(given, str) else None,
        "family_sha256": family_sha256(fam),
        "family_record": fam.to_dict(),
    }


def _map(fn, jobs: list, workers: int):
    """``map`` in order over ``workers`` processes (results do not depend on the count)."""
    if workers <= 1 or len(jobs) < 2:
        yield from map(fn, jobs)
        return

    ctx = pool_context()
    with ctx.Pool(workers) as pool:
        yield from pool.imap(fn, jobs, chunksize=1)


class CachedSuite:
    """A written suite: ``len``, ``manifest``, ``load(i) -> SuiteFlight`` (reads the CSV log)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        mf = self.path / "suite.json"
        if not mf.is_file():
            raise InputError(
                "not a suite folder (no suite.json; write one with rfsl dataset --suite unseen "
                "--logs)",
                source=str(self.path),
            )
        self.manifest = _manifest(mf)

    def __len__(self) -> int:
        return len(self.manifest["flights"])

    def load(self, i: int) -> SuiteFlight:
        r = self.manifest["flights"][i]
        return SuiteFlight(
            read_flight_log(self.path / r["file"]), np.array(r["truth_xy"]), r["draw"]
        )

    def family(self) -> FamilyArg:
        """The family the cache was drawn from: a built-in name, or the ``PhysicsFamily`` its
        manifest keeps."""
        rec = self.manifest.get("family_record")
        if rec is None:
            return self.manifest.get("family", "afar")

        return PhysicsFamily.from_dict(rec, source=str(self.path / "suite.json"))

    def rewrite_command(self) -> str:
        """The ``rfsl dataset`` command that writes this cache again with the current code."""
        mf = self.manifest
        cmd = f"rfsl dataset --suite unseen --logs --n {len(self)} --seed {mf.get('seed')}"
        fam = mf.get("family_path") or mf.get("family", "afar")
        if fam != "afar":
            cmd += f" --family {fam}"
        if mf.get("center", "afar") != "afar":
            cmd += f" --center {mf['center']}"
        return f"{cmd} --out {self.path} --overwrite"

    def check_current(self) -> str | None:
        """A one-line warning if this cache is not what this code simulates (flight 0 re-simulated),
        else None."""
        fp = self.manifest.get("fingerprint")
        redo = f"rewrite it with {self.rewrite_command()}"
        if (
            not isinstance(fp, dict)
            or not fp.get("sha256")
            or fp.get("scheme") != FINGERPRINT_SCHEME
        ):
            why = (
                "no fingerprint in suite.json: written before fingerprints"
                if not isinstance(fp, dict)
                else f"fingerprint scheme {fp.get('scheme')!r} unknown to this code"
            )
            return (
                f"{self.path} may have been written by other simulator code than this one "
                f"({why}): its figures "
                f"may not be the current code's; {redo}"
            )
        mf = self.manifest
        i = int(fp.get("flight", 0))
        try:
            now = flight_fingerprint(
                unseen_flight(int(mf["seed"]), i, self.family(), mf.get("center", "afar"))
            )
        except (InputError, KeyError, ValueError) as e:
            return (
                f"{self.path}: this code cannot re-simulate its flight {i} "
                f"({str(e).splitlines()[0]}): its "
                f"figures may not be the current code's; {redo}"
            )
        if now == fp["sha256"]:
            return None
        return (
            f"{self.path} was written by other simulator code than this one (fingerprint of "
            f"flight {i} "
            f"differs): its figures are not the current code's; {redo}"
        )


def _manifest(mf: Path) -> dict:
    """``suite.json`` read and checked where the readers index it (``mission.fields``): its
    format, and each flight's ``file``, ``truth_xy`` and ``draw``; one line naming the file and
    field otherwise."""
    src = str(mf)
    try:
        m = json.loads(read_text(mf, "suite manifest", max_bytes=100_000_000))
    except (ValueError, RecursionError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(f"not valid JSON ({str(e).splitlines()[0][:80]})", source=src) from None
    f = Fields(m if m is not None else [], src, shape="a suite manifest (a JSON object)")
    if f.raw("format") != FORMAT:
        raise InputError(f"unknown suite format {m.get('format')!r}", source=src)
    f.typed("flights", (list,))
    for i, r in enumerate(f.raw("flights", REQUIRED)):
        fl = Fields(r, src, f"flights[{i}]", shape="{file, truth_xy, draw}")
        fl.str_("file")
        fl.span("truth_xy", ordered=False)  # the transmitter's (x, y), metres
        fl.sub("draw", REQUIRED)
    return m


def read_suite(path: str | Path) -> CachedSuite:
    """A suite folder written by ``write_suite`` (``rfsl dataset --suite unseen --logs``)."""
    return CachedSuite(path)
