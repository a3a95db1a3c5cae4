"""Train a localizer network on simulated datasets and export it to ONNX (needs the ``[train]``
extra: torch).

Recipe (all seeded: ``torch.manual_seed``, deterministic algorithms, numpy generator for the split):

- Inputs: the dataset's ``clustering`` (3 C_k) or ``normalised_rss`` (L) arrays of one or more
  datasets that share the feature configuration and the field origin; targets: the true transmitter
  (x, y).
- Coordinates (``coords``, clustering only): ``"relative"`` (default) subtracts the strongest
  cluster's (x_1, y_1) from every cluster's (x, y) and predicts ``truth - (x_1, y_1)`` -- a
  translation-equivariant parametrisation (with dipoles the RSS peaks on a ring around the
  transmitter, so the strongest cluster is near, not at, the transmitter, and the offset generalises
  across positions and trajectories); ``"absolute"`` is the original one.  Both are done inside the
  exported graph (``nets.CoordinateWrapper``): the ONNX model takes the raw features and returns
  metres.
- Standardisation: clustering inputs per *feature type* (one mean/std pooled over all clusters' RSS,
  one over all x, one over all y, so clusters stay on one scale), computed on the (relative or
  absolute) training features; normalised-RSS inputs by one scalar pair; outputs per coordinate (of
  ``truth - ref``). The statistics are buffers of the exported graph; the ONNX metadata's
  ``input_normalisation`` is the identity (zeros / ones), so ``OnnxLocalizer`` passes the raw
  features (the contract is unchanged).
- Altitude normalisation (``altitude_normalised``, clustering only, off by default): every flight's
  cluster (x, y) and truth are scaled by ``REFERENCE_HEIGHT_M / height above the transmitter`` about
  the field origin (``mission.localize.altitude_scale``: free space with direction-only gains is
  scale-invariant); the metadata tells ``OnnxLocalizer`` to scale at inference.  Validation errors
  stay in metres.
- Split (``validation_split``): a seeded random ``val_fraction`` of the flights held out for early
  stopping.
- Optimiser: AdamW, cosine learning-rate decay over ``epochs``, early stopping after ``patience``
  epochs without a better validation mean error; the best weights are kept.
- Augmentation (clustering only, train split, fresh each batch) against the sim-to-real gap: the
  relative cluster RSS is scaled by a random factor (real path-loss slopes and antenna gains differ
  from the model's), jittered per cluster, positions jittered (GPS), and the clusters re-sorted by
  RSS so the order rule still holds (the reference cluster is the strongest one *after* the
  augmentation, as at inference). A constant offset needs no augmentation: the features are
  offset-invariant.
- Export: ``torch.onnx.export`` (opset 17, dynamic batch), metadata_props in the keys that
  ``mission.localize.card.ModelCard`` reads (``feature_kind``, ``feature_config``,
  ``input_normalisation``, ``field_origin``, ``training_data``), then onnxruntime is run on
  validation inputs and must match torch to 1e-4; the JSON card beside the model gets the training
  domain (``mission.workshop.domain.write_domain``: altitude and attitude spans), which the runtime
  reads.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import onnxruntime as ort

from mission.errors import InputError
from mission.localize.altitude_scale import (
    METADATA_KEY,
    metadata_entry,
    scale_cluster_xy,
    scale_factor,
)
from mission.localize.features import FeatureConfig
from mission.workshop.dataset import dataset_heights, load_dataset, physics_label
from mission.workshop.domain import write_domain


@dataclass(frozen=True)
class TrainConfig:
    """Training settings (recorded in the model's ``training_data`` metadata)."""

    features: str = "clustering"
    epochs: int = 300
    batch_size: int = 128
    lr: float = 2e-3
    weight_decay: float = 1e-4
    val_fraction: float = 0.15
    patience: int = 40
    seed: int = 0
    threads: int = 2
    augment: bool = True
    aug_rss_scale: tuple[float, float] = (0.6, 1.8)
    aug_rss_noise_db: float = 1.0
    aug_pos_noise_m: float = 2.0
    net: dict = field(default_factory=dict)
    max_train: int | None = None  # cap the number of flights used (quick runs)
    coords: str = "relative"  # clustering: "relative" (to the strongest cluster) or "absolute"
    max_minutes: float | None = (
        None  # wall-time budget: stop after the epoch that passes it (best state kept)
    )
    altitude_normalised: bool = (
        False  # clustering: coordinates in units of the flight's height (altitude_scale)
    )


@dataclass
class TrainResult:
    """What training produced: the ONNX path, metrics, timing and complexity."""

    onnx_path: Path
    metrics: dict
    history: list[dict]
    seconds: float
    n_params: int
    flops: int
    max_onnx_diff: float
    meta: dict


def load_training_data(
    paths: Sequence[str | Path], kind: str
) -> tuple[np.ndarray, np.ndarray, dict]:
    """Features (N, F) float32 and targets (N, 2) of one or more datasets, plus a description of
    them."""
    xs, ys, descr = [], [], []
    fcfg = origin = None
    for p in paths:
        arrays, m = load_dataset(p, (kind, "tx_enu"))
        if fcfg is None:
            fcfg, origin = FeatureConfig.normalised(m["feature_config"]), m["field_origin"]
        elif FeatureConfig.normalised(m["feature_config"]) != fcfg:
            raise InputError("datasets differ in their feature configuration", source=str(p))
        elif m["field_origin"] != origin:
            raise InputError("datasets differ in their field origin", source=str(p))
        xs.append(arrays[kind])
        ys.append(arrays["tx_enu"][:, :2])
        cfg = dict(m["config"])
        descr.append(
            {
                "path": str(p),
                "n": m["n"],
                "model": physics_label(cfg),
                "seed": cfg.get("seed"),
                "mission": cfg.get("mission"),
                "mission_name": m.get("mission_name"),
                "mission_altitude_m": m.get("mission_altitude_m"),
                "randomisation": cfg.get("randomisation"),
                "software_version": m.get("software_version"),
            }
        )
    return (
        np.concatenate(xs).astype(np.float32),
        np.concatenate(ys).astype(np.float32),
        {"datasets": descr, "feature_config": fcfg, "field_origin": origin},
    )


def normalisation(x: np.ndarray, y: np.ndarray, kind: str) -> dict:
    """Input/output standardisation statistics (see the module docstring)."""
    if kind == "clustering":
        c = x.shape[1] // 3
        v = x.reshape(len(x), c, 3)
        mean = v.mean(axis=(0, 1))
        std = np.maximum(v.std(axis=(0, 1)), 1e-3)
        in_mean, in_std = np.tile(mean, c), np.tile(std, c)
    else:
        in_mean = np.array([x.mean()])
        in_std = np.array([max(float(x.std()), 1e-3)])
    return {
        "input_mean": [float(v) for v in in_mean],
        "input_std": [float(v) for v in in_std],
        "output_mean": [float(v) for v in y.mean(axis=0)],
        "output_std": [float(v) for v in np.maximum(y.std(axis=0), 1e-3)],
    }


def _augment(xb, cfg: TrainConfig, gen):
    """Clustering-feature augmentation on a raw (B, 3C) batch (torch), then re-sort by RSS
    descending."""
    # torch (and onnx) stay lazy (noqa): the optional [train] extra, absent from a runtime
    # install
    import torch  # noqa: PLC0415

    b, f = xb.shape
    v = xb.reshape(b, f // 3, 3).clone()
    lo, hi = cfg.aug_rss_scale
    scale = torch.exp(torch.empty(b, 1).uniform_(math.log(lo), math.log(hi), generator=gen))
    p = v[:, :, 0] * scale + torch.randn(b, f // 3, generator=gen) * cfg.aug_rss_noise_db
    v[:, :, 0] = p
    v[:, :, 1:] += torch.randn(b, f // 3, 2, generator=gen) * cfg.aug_pos_noise_m
    order = torch.argsort(-p, dim=1, stable=True)
    v = torch.gather(v, 1, order.unsqueeze(-1).expand(-1, -1, 3))
    return v.reshape(b, f)


def validation_split(n: int, cfg: TrainConfig) -> tuple[np.ndarray, np.ndarray]:
    """Sorted (validation, training) indices: ``val_fraction`` of the first ``max_train`` of a
    seeded permutation of ``n`` flights; the one place the split is drawn (tests recompute metrics
    on it)."""
    # max_train None: every flight
    perm = np.random.default_rng(cfg.seed).permutation(n)[: cfg.max_train]
    n_val = max(1, int(round(cfg.val_fraction * len(perm))))
    if len(perm) - n_val < 2:
        raise InputError(f"too few flights ({len(perm)}) to train and validate")
    return np.sort(perm[:n_val]), np.sort(perm[n_val:])


def train(
    paths: Sequence[str | Path],
    out: str | Path,
    cfg: TrainConfig | None = None,
    progress: Callable[[int, int, dict], None] | None = None,
) -> TrainResult:
    """Train on the datasets ``paths`` and write the ONNX model to ``out`` (plus ``out`` +
    ``.train.json``).  Phases: the settings checked, the arrays loaded (and altitude-normalised),
    the network built around their normalisation, the epochs, the model card and its files."""
    # torch stays lazy (noqa): the optional [train] extra, absent from a runtime install
    import torch  # noqa: PLC0415

    cfg = cfg or TrainConfig()
    relative = _checked_coords(cfg)
    t_start = time.perf_counter()
    torch.manual_seed(cfg.seed)
    torch.use_deterministic_algorithms(True)
    torch.set_num_threads(max(1, cfg.threads))
    x, y, scale, data_descr = _training_arrays(paths, cfg)
    val_idx, tr_idx = validation_split(len(x), cfg)
    n_in = x.shape[1]
    xt, yt = torch.from_numpy(x), torch.from_numpy(y)
    x_tr, y_tr = xt[tr_idx], yt[tr_idx]
    val = (
        xt[val_idx],
        yt[val_idx],
        torch.from_numpy(scale[val_idx].astype(np.float32)),  # validation errors back in metres
    )
    net, norm, n_params, flops = _build(cfg, x_tr, y_tr, n_in, relative)
    history, best_epoch = _fit(net, cfg, x_tr, y_tr, val, progress, t_start)
    err = _val_errors(net, *val)
    metrics = {
        "val_mean_m": float(err.mean()),
        "val_median_m": float(np.median(err)),
        "val_p90_m": float(np.percentile(err, 90)),
        "best_epoch": best_epoch,
        "epochs_run": len(history),
        "n_train": int(len(tr_idx)),
        "n_val": int(len(val_idx)),
    }
    seconds = time.perf_counter() - t_start
    meta = _model_meta(cfg, data_descr, n_in, relative, norm, metrics, n_params, flops, seconds)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    diff = export_onnx(net, n_in, out, meta, val[0][:256])
    # the card the runtime reads: the training's altitude, attitude
    write_domain(out, meta["training_data"])
    res = TrainResult(out, metrics, history, seconds, n_params, flops, diff, meta)
    Path(str(out) + ".train.json").write_text(
        json.dumps(
            {
                "metrics": metrics,
                "history": history,
                "seconds": round(seconds, 1),
                "n_params": n_params,
                "flops": flops,
                "max_onnx_diff": diff,
                "training_data": meta["training_data"],
            },
            indent=1,
        )
    )
    return res


def _checked_coords(cfg: TrainConfig) -> bool:
    """Refuse settings that name no feature kind or coordinates; whether the coordinates are
    relative to the strongest cluster."""
    if cfg.features not in ("clustering", "normalised_rss"):
        raise InputError(f"unknown feature kind {cfg.features!r}", field="--features")
    if cfg.coords not in ("relative", "absolute"):
        raise InputError(
            f"unknown coordinates {cfg.coords!r} (relative or absolute)", field="--coords"
        )
    if cfg.altitude_normalised and cfg.features != "clustering":
        raise InputError(
            "altitude normalisation needs clustering features", field="--altitude-normalised"
        )
    return cfg.coords == "relative" and cfg.features == "clustering"


def _training_arrays(
    paths: Sequence[str | Path], cfg: TrainConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """(features, targets, per-flight scale, description) of the datasets; with
    ``altitude_normalised`` the positions in units of each flight's height (scale 1 otherwise)."""
    x, y, data_descr = load_training_data(paths, cfg.features)
    scale = np.ones(len(x))
    if cfg.altitude_normalised:
        scale = scale_factor(
            np.concatenate(
                [dataset_heights(load_dataset(p, ("params",))[0]["params"]) for p in paths]
            )
        )
        x, y = (
            scale_cluster_xy(x, scale).astype(np.float32),
            (y * scale[:, None]).astype(np.float32),
        )
    return x, y, scale, data_descr


def _build(cfg: TrainConfig, x_tr, y_tr, n_in: int, relative: bool):
    """(network in its coordinate wrapper, the normalisation it holds, parameters, FLOPs): the
    normalisation is measured on the training flights as the wrapper presents them."""
    # torch and mission.workshop.nets (torch at its top) stay lazy (noqa): the optional [train]
    # extra, absent from a runtime install
    import torch  # noqa: PLC0415

    from mission.workshop.nets import (  # noqa: PLC0415
        CoordinateWrapper,
        build_net,
        count_flops,
        count_parameters,
    )

    inner = build_net(cfg.features, n_in, **cfg.net)
    one = torch.ones(1)
    probe = CoordinateWrapper(inner, 0 * one, one, torch.zeros(2), torch.ones(2), relative, n_in)
    with torch.no_grad():
        rel_tr, ref_tr = probe.split(x_tr)
    norm = normalisation(rel_tr.numpy(), (y_tr - ref_tr).numpy(), cfg.features)
    net = CoordinateWrapper(
        inner,
        torch.tensor(norm["input_mean"]),
        torch.tensor(norm["input_std"]),
        torch.tensor(norm["output_mean"]),
        torch.tensor(norm["output_std"]),
        relative,
        n_in,
    )
    # + the wrapper's shift / scale (negligible)
    flops = count_flops(inner, n_in) + (2 * n_in + 6) * 2
    return net, norm, count_parameters(net), flops


def _val_errors(net, x_val, y_val, s_val) -> np.ndarray:
    """Validation errors (m, back in metres for altitude-normalised flights), the net left in
    training mode."""
    import torch  # noqa: PLC0415  (the optional [train] extra)

    net.eval()
    with torch.no_grad():
        pred = torch.cat([net(x_val[i : i + 1024]) for i in range(0, len(x_val), 1024)])
    net.train()
    return (torch.linalg.norm(pred - y_val, dim=1) / s_val).numpy()


def _fit(net, cfg: TrainConfig, x_tr, y_tr, val: tuple, progress, t_start: float):
    """The epochs (AdamW, cosine schedule, smooth L1 on standardised outputs, early stop on the
    validation mean, the time budget); the best epoch's weights are loaded into ``net``.  Returns
    (history, best epoch)."""
    import torch  # noqa: PLC0415  (the optional [train] extra)

    out_std = net.out_std
    out_mean = net.out_mean
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(
        opt, T_max=max(1, cfg.epochs), eta_min=cfg.lr * 0.01
    )
    gen = torch.Generator().manual_seed(cfg.seed)
    loss_fn = torch.nn.SmoothL1Loss(beta=0.1)
    best = (math.inf, -1)
    best_state = None
    history: list[dict] = []
    bs = cfg.batch_size
    augment = cfg.augment and cfg.features == "clustering"
    for epoch in range(cfg.epochs):
        net.train()
        order = torch.randperm(len(x_tr), generator=gen)
        tot = 0.0
        nb = 0
        for i in range(0, len(order) - (1 if len(order) % bs == 1 else 0), bs):
            idx = order[i : i + bs]
            xb = x_tr[idx]
            if augment:
                xb = _augment(xb, cfg, gen)
            z, ref = net.forward_standardised(xb)
            yb = (y_tr[idx] - ref - out_mean) / out_std
            opt.zero_grad(set_to_none=True)
            loss = loss_fn(z, yb)
            loss.backward()
            opt.step()
            tot += float(loss.detach())
            nb += 1
        sched.step()
        err = _val_errors(net, *val)
        rec = {
            "epoch": epoch + 1,
            "train_loss": tot / max(nb, 1),
            "val_mean_m": float(err.mean()),
            "val_median_m": float(np.median(err)),
            "lr": float(opt.param_groups[0]["lr"]),
        }
        history.append(rec)
        if rec["val_mean_m"] < best[0]:
            best = (rec["val_mean_m"], epoch + 1)
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        if progress:
            progress(epoch + 1, cfg.epochs, rec)
        if epoch + 1 - best[1] >= cfg.patience:
            break
        if cfg.max_minutes is not None and time.perf_counter() - t_start > 60.0 * cfg.max_minutes:
            break  # time budget spent (a shared machine); the best epoch so far is exported
    assert best_state is not None
    net.load_state_dict(best_state)
    return history, best[1]


def _model_meta(
    cfg: TrainConfig,
    data_descr: dict,
    n_in: int,
    relative: bool,
    norm: dict,
    metrics: dict,
    n_params: int,
    flops: int,
    seconds: float,
) -> dict:
    """The ONNX metadata (the contract with ``mission.localize.card``) and the training record."""
    import torch  # noqa: PLC0415  (the optional [train] extra)

    return {
        "feature_kind": cfg.features,
        "feature_config": data_descr["feature_config"],
        "input_normalisation": {  # identity: the graph standardises internally (CoordinateWrapper)
            "input_mean": [0.0] * n_in,
            "input_std": [1.0] * n_in,
            "output_mean": [0.0, 0.0],
            "output_std": [1.0, 1.0],
        },
        "field_origin": data_descr["field_origin"],
        "training_data": {
            "datasets": data_descr["datasets"],
            "train_config": _jsonable(asdict(cfg)),
            "coords": "relative" if relative else "absolute",
            "parametrisation": (
                "inside the graph: (x, y) of every cluster minus the strongest cluster's (x_1, "
                "y_1), "
                "standardised; output + (x_1, y_1)"
                if relative
                else "inside the graph: absolute (x, y), standardised"
            ),
            "graph_normalisation": norm,
            **({METADATA_KEY: metadata_entry()} if cfg.altitude_normalised else {}),
            "metrics": metrics,
            "n_params": n_params,
            "flops": flops,
            "train_seconds": round(seconds, 1),
            "torch": torch.__version__,
        },
    }


def _jsonable(d):
    return json.loads(json.dumps(d, default=lambda o: list(o) if isinstance(o, tuple) else str(o)))


def export_onnx(
    net, n_in: int, path: str | Path, meta: dict, check_inputs=None, tol: float = 1e-4
) -> float:
    """Export ``net`` (eval mode) to ONNX opset 17 with a dynamic batch axis, attach ``meta`` as
    metadata_props (JSON strings; ``feature_kind`` as plain text), and check onnxruntime against
    torch.

    Returns the largest absolute difference on ``check_inputs`` (the raw inputs the graph takes);
    raises if > ``tol`` (relative to the output scale: metres for the wrapped localizer, so ``tol``
    is scaled by ``max(1, |output|)``).
    """
    # torch (and onnx) stay lazy (noqa): the optional [train] extra, absent from a runtime
    # install
    import onnx  # noqa: PLC0415
    import torch  # noqa: PLC0415

    path = Path(path)
    net.eval()
    dummy = torch.zeros(1, n_in)
    # the TorchScript exporter is deprecated but needs no onnxscript
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        warnings.filterwarnings("ignore", message="Constant folding", category=UserWarning)
        torch.onnx.export(
            net,
            (dummy,),
            str(path),
            opset_version=17,
            input_names=["features"],
            output_names=["xy"],
            dynamic_axes={"features": {0: "batch"}, "xy": {0: "batch"}},
            dynamo=False,
        )
    model = onnx.load(str(path))
    del model.metadata_props[:]
    for k, v in meta.items():
        e = model.metadata_props.add()
        e.key = k
        e.value = v if isinstance(v, str) else json.dumps(v)
    model.producer_name = "rfsl train"
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    if check_inputs is None:
        check_inputs = torch.randn(8, n_in)
    with torch.no_grad():
        ref = net(check_inputs).numpy()
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    got = sess.run(None, {"features": check_inputs.numpy().astype(np.float32)})[0]
    diff = float(np.max(np.abs(got - ref) / np.maximum(1.0, np.abs(ref))))
    if diff > tol:
        raise RuntimeError(f"onnxruntime output differs from torch by {diff:.2e} (> {tol:g})")
    return diff
