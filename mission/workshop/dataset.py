"""Simulated training/test datasets: many transmitter positions, each flown in the simulator, stored
as compact feature chunks.

Where things live: the configuration and its randomisation in ``mission.workshop.dataset_config``;
drawing and flying one flight in ``mission.workshop.flight_draws``; workers, chunk files and reading
here (the names of all three are importable from this module).

raw truth, ``params`` (n, len(PARAM_NAMES)), ``n_samples`` (n,) int32 and ``index`` (n,) int64.
Chunks are written as they complete, so memory stays bounded by ``chunk`` flights.
"""

from __future__ import annotations

import hashlib
import io
import json
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from mission import __version__
from mission.adaptive.planner import flown_ahead
from mission.errors import InputError
from mission.fields import REQUIRED, Fields
from mission.files import read_text, write_bytes, write_text
from mission.localize.features import FeatureConfig
from mission.spec import load_mission
from mission.threads import limit_worker, pool_context

# re-exported: one import site for dataset users
from mission.workshop.dataset_config import (  # noqa: F401
    FEATURE_KINDS,
    PARAM_NAMES,
    DatasetConfig,
    Randomisation,
    check_config,
    pattern_names,
    physics_label,
    trajectory_names,
)
from mission.workshop.flight_draws import (  # noqa: F401
    FlightDraw,
    FlightSimulator,
    flight_rng,
    trajectory_params,
)
from mission.workshop.suite import family_label, family_sha256, resolve_family

FORMAT = "rfsl-dataset/1"

# -------------------------------------------------------------------------------------- workers,
# chunks

_WORKER: FlightSimulator | None = None


def _init_worker(cfg_dict: dict) -> None:
    global _WORKER

    limit_worker()
    _WORKER = FlightSimulator(DatasetConfig.from_dict(cfg_dict))


def _work(i: int) -> dict[str, np.ndarray]:
    assert _WORKER is not None
    return _WORKER.features(_WORKER.draw(i))


def _stack(rows: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    out = {}
    for k in rows[0]:
        a = np.stack([r[k] for r in rows])
        if k == "n_samples":
            out[k] = a.astype(np.int32)
        elif k == "index":
            out[k] = a.astype(np.int64)
        else:
            out[k] = a.astype(np.float32)
    return out


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """Deterministic npz bytes (``np.savez_compressed`` writes fixed zip timestamps)."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def iter_rows(
    cfg: DatasetConfig, workers: int = 1, indices: Sequence[int] | None = None
) -> Iterator[dict[str, np.ndarray]]:
    """Rows of flights ``indices`` (default all) in index order, computed by ``workers``
    processes."""
    idx = list(range(cfg.n)) if indices is None else list(indices)
    if workers <= 1:
        _init_worker(cfg.to_dict())
        for i in idx:
            yield _work(i)
        return

    with pool_context().Pool(workers, initializer=_init_worker, initargs=(cfg.to_dict(),)) as pool:
        yield from pool.imap(_work, idx, chunksize=4)


def generate_dataset(
    cfg: DatasetConfig,
    out_dir: str | Path,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
) -> dict:
    """Simulate all flights of ``cfg`` and write the chunks and the manifest to ``out_dir``.

    ``progress(done, total)`` is called after each flight.  Returns the manifest.
    """
    out = _prepare(cfg, out_dir, overwrite)
    spec = flown_ahead(load_mission(cfg.mission))
    fcfg = FeatureConfig.from_dict(cfg.feature_config) if cfg.feature_config else FeatureConfig()
    t0 = time.perf_counter()
    chunks = _write_chunks(cfg, out, workers, progress)
    elapsed = time.perf_counter() - t0
    manifest = {
        "format": FORMAT,
        "software_version": __version__,
        "config": cfg.to_dict(),
        "mission_name": spec.name,
        "mission_generator": spec.trajectory.generator,
        "mission_altitude_m": spec.altitude_m,
        "field_origin": spec.field.origin.to_dict(),
        "feature_config": fcfg.to_dict(),
        "param_names": list(PARAM_NAMES),
        "trajectory_names": trajectory_names(cfg, spec.trajectory.generator),
        "pattern_names": pattern_names(cfg),
        "seeding": "flight i uses np.random.SeedSequence(seed, spawn_key=(i,)) (= "
        "SeedSequence(seed).spawn(n)[i])",
        "chunks": chunks,
        "n": cfg.n,
        **_family_record(cfg),
        "generation": {
            "workers": workers,
            "seconds": round(elapsed, 2),
            "flights_per_s": round(cfg.n / elapsed, 3) if elapsed > 0 else None,
        },
    }
    # the timing block differs between runs; everything else is deterministic
    write_text(out / "manifest.json", json.dumps(manifest, indent=2, default=float))
    return manifest


def _prepare(cfg: DatasetConfig, out_dir: str | Path, overwrite: bool) -> Path:
    """Refuse a bad config or an existing dataset (unless ``overwrite``); the output folder, made
    and emptied of old chunks."""
    check_config(cfg)
    out = Path(out_dir)
    if (out / "manifest.json").exists() and not overwrite:
        raise InputError("a dataset exists already here (use --overwrite)", source=str(out))
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("chunk_*.npz"):
        old.unlink()
    return out


def _write_chunks(
    cfg: DatasetConfig, out: Path, workers: int, progress: Callable[[int, int], None] | None
) -> list[dict]:
    """Simulate the flights (``iter_rows``) and write them ``cfg.chunk`` at a time; each chunk's
    manifest entry (file, count, first index, sha256)."""
    chunks: list[dict] = []
    buf: list[dict[str, np.ndarray]] = []
    done = 0

    def flush() -> None:
        arrays = _stack(buf)
        data = _npz_bytes(arrays)
        name = f"chunk_{len(chunks):05d}.npz"
        write_bytes(out / name, data)
        chunks.append(
            {
                "file": name,
                "n": len(buf),
                "first_index": int(arrays["index"][0]),
                "sha256": hashlib.sha256(data).hexdigest(),
            }
        )
        buf.clear()

    for row in iter_rows(cfg, workers):
        buf.append(row)
        done += 1
        if progress:
            progress(done, cfg.n)
        if len(buf) == cfg.chunk:
            flush()
    if buf:
        flush()
    return chunks


# ---------------------------------------------------------------------------------------------
# reading


def _family_record(cfg: DatasetConfig) -> dict:
    """A suite dataset drawn from a family file keeps the family itself (its sha256 names it; the
    file may move)."""
    if not cfg.suite:
        return {}

    fam = resolve_family(cfg.suite_family)
    if isinstance(fam, str):
        return {}
    return {
        "physics_family": {
            "label": family_label(fam),
            "sha256": family_sha256(fam),
            "record": fam.to_dict(),
        }
    }


def read_manifest(path: str | Path, need: Sequence[str] = ()) -> dict:
    """The manifest of a dataset folder (or of the manifest file itself); ``need``: keys the caller
    reads."""
    p = Path(path)
    mf = p / "manifest.json" if p.is_dir() else p
    if not mf.is_file():
        raise InputError("not a dataset (no manifest.json)", source=str(p))

    try:
        m = json.loads(read_text(mf, "dataset manifest"))
    except (ValueError, RecursionError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(
            f"manifest is not valid JSON ({str(e).splitlines()[0][:80]})", source=str(mf)
        ) from None
    if m is None:
        raise InputError("not a dataset manifest (a JSON object)", source=str(mf))
    f = Fields(m, str(mf), shape="a dataset manifest (a JSON object)")
    for k in need:  # what the caller reads: a list of chunks, objects otherwise (a KeyError before)
        f.raw(k, REQUIRED)
        f.typed(k, (list,) if k == "chunks" else (dict,))
    if m.get("format") != FORMAT:
        raise InputError(
            f"unknown dataset format {m.get('format')!r} (expected {FORMAT})", source=str(mf)
        )
    return m


def load_dataset(
    path: str | Path, keys: Sequence[str] = ("clustering", "tx_enu", "params"), verify: bool = False
) -> tuple[dict[str, np.ndarray], dict]:
    """Concatenate the arrays ``keys`` of all chunks; returns (arrays, manifest).

    ``verify`` checks every chunk's sha256 against the manifest.
    """
    root = Path(path)
    m = read_manifest(root, need=("chunks",))
    parts: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    for i, c in enumerate(m["chunks"]):
        if not (
            isinstance(c, dict)
            and isinstance(c.get("file"), str)
            and Path(c["file"]).name == c["file"]
        ):
            raise InputError(
                "expected {file: chunk_NNNNN.npz, ...} naming a file of the dataset folder",
                source=str(root / "manifest.json"),
                field=f"chunks[{i}]",
            )
        f = root / c["file"]
        if verify:
            h = hashlib.sha256(f.read_bytes()).hexdigest()
            if h != c.get("sha256"):
                raise InputError("chunk digest does not match the manifest", source=str(f))
        try:
            with np.load(f, allow_pickle=False) as z:
                for k in keys:
                    if k not in z:
                        raise InputError(
                            f"dataset has no {k!r} array (generated without it?)", source=str(f)
                        )
                    parts[k].append(z[k])
        except InputError:
            raise
        # zipfile, zlib, numpy and OS errors all mean a damaged or missing chunk
        except Exception as e:
            raise InputError(
                f"damaged or unreadable dataset chunk ({type(e).__name__}: "
                f"{str(e).splitlines()[0][:80] if str(e) else 'no detail'})",
                source=str(f),
            ) from None
    return {k: np.concatenate(v) for k, v in parts.items()}, m


def dataset_config(manifest: dict) -> DatasetConfig:
    """The ``DatasetConfig`` recorded in a manifest (to regenerate flights, e.g. for classical
    methods)."""
    return DatasetConfig.from_dict(manifest["config"])


def dataset_heights(params: np.ndarray) -> np.ndarray:
    """Each simulated flight's height above its transmitter (B,), from a dataset's ``params``
    array."""
    p = np.asarray(params, dtype=float)
    return p[:, PARAM_NAMES.index("altitude_m")] - p[:, PARAM_NAMES.index("tx_height_m")]
