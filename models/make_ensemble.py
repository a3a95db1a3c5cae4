"""Build one ONNX file whose output ``xy`` is the plain mean of N member networks' ``xy`` (same
input ``features``).

Why one file: ``localize --model`` and the fusion take one model; the members run side by side in
one graph (``Mean`` of their outputs), so the ensemble needs nothing at inference beyond
onnxruntime.  The members must share the feature contract (kind, configuration, identity input
normalisation: relative-coordinate graphs, ``rfsl train --coords relative``) and the field origin.
Metadata: member 0's ``metadata_props`` plus ``ensemble`` (JSON: the rule and each member's file
name and sha256).

    python models/make_ensemble.py OUT.onnx MEMBER0.onnx MEMBER1.onnx ... [--check DATASET_DIR]

``--check`` runs every member and the ensemble with onnxruntime on a dataset's clustering features
and fails unless the ensemble equals the members' mean (relative difference < 1e-5).
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
from onnx import compose, helper

from mission.localize.altitude_scale import METADATA_KEY, reference_height
from mission.workshop.dataset import load_dataset

CONTRACT = ("feature_kind", "feature_config", "input_normalisation", "field_origin")


def _reference_height(meta: dict) -> float | None:
    """A member's altitude-normalisation reference (``mission.localize.altitude_scale``); None:
    metres."""
    return reference_height(json.loads(meta.get("training_data", "{}")))


def build(out: str, paths: list[str]) -> None:
    """Write the mean-of-members graph to ``out`` (module docstring)."""
    models = [onnx.load(p) for p in paths]
    m0 = models[0]
    inp, outn = m0.graph.input[0].name, m0.graph.output[0].name
    meta0 = {p.key: p.value for p in m0.metadata_props}
    for p, m in zip(paths, models, strict=True):
        meta = {q.key: q.value for q in m.metadata_props}
        bad = [k for k in CONTRACT if meta.get(k) != meta0.get(k)]
        if _reference_height(meta) != _reference_height(meta0):  # inputs scaled differently
            bad.append(f"training_data.{METADATA_KEY}")
        if bad or m.graph.input[0].name != inp or m.graph.output[0].name != outn:
            raise SystemExit(
                f"{p}: its contract differs from {paths[0]} "
                f"({', '.join(bad) or 'input/output names'})"
            )
    norm = json.loads(meta0["input_normalisation"])
    if not (
        all(v == 0 for v in norm["input_mean"] + norm["output_mean"])
        and all(v == 1 for v in norm["input_std"] + norm["output_std"])
    ):
        raise SystemExit(
            "a mean of outputs needs identity normalisation (relative-coordinate graphs)"
        )
    nodes, inits, vinfo, outs = [], [], [], []
    for i, m in enumerate(models):
        g = compose.add_prefix(m, prefix=f"m{i}_").graph
        for n in g.node:  # every member reads the one shared input
            for j, name in enumerate(n.input):
                if name == f"m{i}_{inp}":
                    n.input[j] = inp
        nodes += list(g.node)
        inits += list(g.initializer)
        vinfo += list(g.value_info)
        outs.append(g.output[0].name)
    nodes.append(helper.make_node("Mean", outs, [outn], name="ensemble_mean"))
    graph = helper.make_graph(
        nodes, "ensemble_mean", [m0.graph.input[0]], [m0.graph.output[0]], inits, value_info=vinfo
    )
    em = helper.make_model(
        graph, opset_imports=list(m0.opset_import), producer_name="models/make_ensemble.py"
    )
    em.ir_version = m0.ir_version
    for k, v in meta0.items():
        em.metadata_props.add(key=k, value=v)
    em.metadata_props.add(
        key="ensemble",
        value=json.dumps(
            {
                "rule": "plain mean of the members' outputs (xy, metres)",
                "members": [
                    {
                        "file": Path(p).name,
                        "sha256": hashlib.sha256(Path(p).read_bytes()).hexdigest(),
                    }
                    for p in paths
                ],
            }
        ),
    )
    em.doc_string = f"plain mean of {len(paths)} networks: " + ", ".join(
        Path(p).name for p in paths
    )
    onnx.checker.check_model(em, full_check=True)
    onnx.save(em, out)
    print("wrote", out, Path(out).stat().st_size, "bytes")


def check(out: str, paths: list[str], dataset: str) -> None:
    """Fail unless ``out`` equals the members' mean on a dataset's clustering features."""
    x = load_dataset(dataset, ("clustering",))[0]["clustering"].astype(np.float32)

    def run(p: str) -> np.ndarray:
        s = ort.InferenceSession(p, providers=["CPUExecutionProvider"])
        return s.run(None, {s.get_inputs()[0].name: x})[0].astype(np.float64)

    ym = np.mean([run(p) for p in paths], axis=0)
    rel = float((np.abs(run(out) - ym) / np.maximum(np.abs(ym), 1.0)).max())
    print(f"{len(x)} feature vectors: max relative difference to the members' mean {rel:.2e}")
    if rel >= 1e-5:
        raise SystemExit("the ensemble does not equal its members' mean")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("members", nargs="+")
    ap.add_argument("--check", help="a dataset folder (rfsl dataset) with clustering features")
    args = ap.parse_args()
    build(args.out, args.members)
    if args.check:
        check(args.out, args.members, args.check)


if __name__ == "__main__":
    main()
