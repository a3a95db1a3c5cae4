"""Train a localizer network on simulated datasets and export it to ONNX (needs the [train] extra:
torch).

Fixed seed, seeded validation split with early stopping, AdamW with cosine decay, input/output
standardisation and (clustering) augmentation; the ONNX file carries the feature configuration, the
normalisation, the field origin and the training-data description in its metadata.
"""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("datasets", nargs="+", help="dataset folder(s) written by `rfsl dataset`")
    p.add_argument("--out", required=True, help="output ONNX file, e.g. models/NAME.onnx")
    p.add_argument(
        "--features",
        default="clustering",
        choices=["clustering", "normalised_rss"],
        help="network input (default clustering = RealAdaptRNet)",
    )
    p.add_argument("--epochs", type=int, default=300, help="maximum epochs (default 300)")
    p.add_argument(
        "--patience", type=int, default=40, help="early-stopping patience in epochs (default 40)"
    )
    p.add_argument("--batch-size", type=int, default=128)
    p.add_argument("--lr", type=float, default=2e-3, help="AdamW learning rate (default 2e-3)")
    p.add_argument(
        "--seed", type=int, default=0, help="seed of weights, split, batches, augmentation"
    )
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    p.add_argument(
        "--no-augment", action="store_true", help="switch training-time augmentation off"
    )
    p.add_argument("--max-train", type=int, help="use at most this many flights (quick runs)")
    p.add_argument(
        "--max-minutes",
        type=float,
        help="wall-time budget: stop after the epoch that passes it, "
        "export the best epoch so far (metadata records the budget)",
    )
    p.add_argument(
        "--coords",
        default="relative",
        choices=["relative", "absolute"],
        help="clustering coordinates: relative to the strongest cluster (default; "
        "translation-equivariant, "
        "done inside the exported graph) or absolute",
    )
    p.add_argument(
        "--family",
        metavar="F.json",
        help="the physics family file the datasets were drawn from (rfsl dataset --family F.json): "
        "checked against every dataset's manifest and recorded in the model's training_data",
    )
    p.add_argument(
        "--altitude-normalised",
        action="store_true",
        help="clustering: coordinates in units of each flight's height above the transmitter, "
        "so one "
        "network serves every altitude (train on a range of altitudes, e.g. rfsl dataset "
        "--altitude 15,60)",
    )


def run(args: argparse.Namespace) -> int:
    # before the (slow) torch import
    family = check_family(args.family, args.datasets) if args.family else None
    try:
        import torch  # noqa: F401
    except ImportError:
        from mission.errors import InputError

        raise InputError("training needs PyTorch: pip install -e '.[train]'") from None
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from mission.workshop.train import TrainConfig, train

    cfg = TrainConfig(
        features=args.features,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        patience=args.patience,
        seed=args.seed,
        threads=args.threads,
        augment=not args.no_augment,
        max_train=args.max_train,
        max_minutes=args.max_minutes,
        coords=args.coords,
        altitude_normalised=args.altitude_normalised,
    )
    console = Console()
    with Progress(
        TextColumn("[bold]train"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        console=console,
    ) as prog:
        task = prog.add_task("", total=cfg.epochs)

        def cb(epoch: int, total: int, rec: dict) -> None:
            prog.update(
                task,
                completed=epoch,
                description=f"val mean {rec['val_mean_m']:.1f} m, "
                f"median {rec['val_median_m']:.1f} m, loss {rec['train_loss']:.4f}",
            )

        res = train(args.datasets, args.out, cfg, progress=cb)
    if family is not None:
        record_family(res.onnx_path, family)
    from mission.shipped import record_shipped_digest

    if record_shipped_digest(res.onnx_path):
        console.print(
            f"recorded its sha256 in models/sha256.json ({res.onnx_path.name} is a shipped network)"
        )
    m = res.metrics
    console.print(
        f"{args.features} ({res.meta['training_data']['coords']} coordinates"
        f"{', altitude-normalised' if cfg.altitude_normalised else ''}): "
        f"{res.n_params / 1e6:.3f} M parameters, "
        f"{res.flops / 1e6:.2f} M FLOPs; "
        f"best epoch {m['best_epoch']} of {m['epochs_run']}; validation mean "
        f"{m['val_mean_m']:.2f} m, "
        f"median {m['val_median_m']:.2f} m, p90 {m['val_p90_m']:.2f} m ({m['n_val']} flights)"
    )
    console.print(
        f"trained in {res.seconds:.0f} s on {args.threads} thread(s); onnxruntime vs torch max "
        "diff "
        f"{res.max_onnx_diff:.1e}; model: {res.onnx_path}"
    )
    return 0


def check_family(path: str, datasets: list[str]) -> dict:
    """The family file's record (label, sha256, record); every dataset must have been drawn from
    it."""
    from mission.errors import InputError
    from mission.workshop.dataset import read_manifest
    from mission.workshop.suite import family_label, family_sha256, resolve_family

    if not path.lower().endswith(".json"):
        raise InputError(
            "give the physics family file (.json) the datasets were drawn from", field="--family"
        )
    fam = resolve_family(path)
    sha = family_sha256(fam)
    for d in datasets:
        got = (read_manifest(d).get("physics_family") or {}).get("sha256")
        if got != sha:
            raise InputError(
                f"dataset was not drawn from {path} "
                f"({'another family' if got else 'no family file'}; "
                f"rfsl dataset --family {path})",
                source=str(d),
                field="--family",
            )
    return {"label": family_label(fam), "path": path, "sha256": sha, "record": fam.to_dict()}


def record_family(onnx_path, family: dict) -> None:
    """Add ``physics_family`` to the model's ``training_data`` metadata (what the card and localize
    read)."""
    import json
    from pathlib import Path

    import onnx

    m = onnx.load(str(onnx_path))
    props = {p.key: p for p in m.metadata_props}
    td = json.loads(props["training_data"].value)
    td["physics_family"] = family
    props["training_data"].value = json.dumps(td)
    onnx.save(m, str(onnx_path))
    # the training report beside the model says the same
    side = Path(str(onnx_path) + ".train.json")
    if side.is_file():
        rep = json.loads(side.read_text())
        rep.setdefault("training_data", {})["physics_family"] = family
        side.write_text(json.dumps(rep, indent=1))
