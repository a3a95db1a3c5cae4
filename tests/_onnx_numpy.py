"""A from-scratch float64 numpy evaluator of the shipped networks' ONNX graphs: an independent
reference for onnxruntime (and for ``OnnxLocalizer``'s normalisation) in ``test_shipped_model``.

Only the operators the shipped graphs use, with the ONNX semantics written out here (1-D Conv,
AveragePool, Gemm, Slice, Pad, ...); an unknown operator fails loudly rather than being skipped.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import onnx
from onnx import helper, numpy_helper


def _conv1d(
    x: np.ndarray, w: np.ndarray, b: np.ndarray | None, stride: int, pads: list[int]
) -> np.ndarray:
    """ONNX Conv, 1-D, group 1, dilation 1: x (B, C, L), w (M, C, K) -> (B, M, L_out)."""
    xp = np.pad(x, ((0, 0), (0, 0), (pads[0], pads[1])))
    k = w.shape[2]
    n_out = (xp.shape[2] - k) // stride + 1
    # (B, C, L, K)
    cols = np.stack([xp[:, :, i * stride : i * stride + k] for i in range(n_out)], axis=2)
    y = np.einsum("bclk,mck->bml", cols, w)
    return y if b is None else y + b[None, :, None]


def _avgpool1d(x: np.ndarray, kernel: int, stride: int, ceil_mode: bool) -> np.ndarray:
    """ONNX AveragePool, 1-D, no padding: a window cut by the end (ceil_mode) averages what it
    covers."""
    length = x.shape[2]
    rnd = math.ceil if ceil_mode else math.floor
    n_out = int(rnd((length - kernel) / stride)) + 1
    return np.stack(
        [x[:, :, i * stride : min(i * stride + kernel, length)].mean(axis=2) for i in range(n_out)],
        axis=2,
    )


def _slice(x: np.ndarray, starts, ends, axes=None, steps=None) -> np.ndarray:
    axes = range(len(starts)) if axes is None else axes
    steps = [1] * len(starts) if steps is None else steps
    idx = [slice(None)] * x.ndim
    for s, e, a, st in zip(starts, ends, axes, steps, strict=True):
        big = np.iinfo(np.int64).max // 2
        idx[int(a)] = slice(int(s), None if abs(int(e)) > big else int(e), int(st))
    return x[tuple(idx)]


def _pad(x: np.ndarray, pads: np.ndarray, value: float = 0.0) -> np.ndarray:
    n = x.ndim
    return np.pad(x, [(int(pads[i]), int(pads[i + n])) for i in range(n)], constant_values=value)


def run_graph(path: str | Path, features: np.ndarray) -> np.ndarray:
    """The graph's first output for ``features`` (B, F), evaluated in float64."""
    model = onnx.load(str(path))
    g = model.graph
    env: dict[str, np.ndarray] = {
        t.name: numpy_helper.to_array(t).astype(np.float64) for t in g.initializer
    }
    inp = g.input[0]
    x = np.asarray(features, dtype=np.float64)
    if len(inp.type.tensor_type.shape.dim) == 3:
        x = x[:, None, :]
    env[inp.name] = x
    for node in g.node:
        a = {at.name: helper.get_attribute_value(at) for at in node.attribute}
        ins = [env[n] if n else None for n in node.input]
        op = node.op_type
        if op == "Constant":
            out = numpy_helper.to_array(a["value"])
        elif op == "ConstantOfShape":
            v = numpy_helper.to_array(a["value"]) if "value" in a else np.zeros(1)
            out = np.full(ins[0].astype(int), v.ravel()[0], dtype=v.dtype)
        elif op == "Reshape":
            out = ins[0].reshape(ins[1].astype(int))
        elif op == "Gather":
            out = np.take(ins[0], ins[1].astype(int), axis=a.get("axis", 0))
        elif op == "Slice":
            out = _slice(ins[0], *[None if v is None else v.astype(np.int64) for v in ins[1:]])
        elif op == "Concat":
            out = np.concatenate(ins, axis=a["axis"])
        elif op == "Transpose":
            out = np.transpose(ins[0], a.get("perm"))
        elif op == "Cast":
            out = ins[0].astype(np.int64 if a["to"] == 7 else np.float64)
        elif op == "Pad":
            out = _pad(ins[0], ins[1], 0.0 if len(ins) < 3 or ins[2] is None else float(ins[2]))
        elif op == "Unsqueeze":
            out = np.expand_dims(ins[0], tuple(int(v) for v in ins[1]))
        elif op in ("Add", "Sub", "Mul", "Div"):
            out = {"Add": np.add, "Sub": np.subtract, "Mul": np.multiply, "Div": np.divide}[op](
                ins[0], ins[1]
            )
        elif op == "Mean":  # an ensemble's plain mean of its members' outputs
            out = np.mean(np.stack(ins), axis=0)
        elif op == "Relu":
            out = np.maximum(ins[0], 0.0)
        elif op == "Conv":
            assert a.get("group", 1) == 1 and list(a.get("dilations", [1])) == [1], node
            out = _conv1d(
                ins[0], ins[1], ins[2] if len(ins) > 2 else None, a["strides"][0], list(a["pads"])
            )
        elif op == "AveragePool":
            assert list(a.get("pads", [0, 0])) == [0, 0], node
            out = _avgpool1d(
                ins[0], a["kernel_shape"][0], a["strides"][0], bool(a.get("ceil_mode", 0))
            )
        elif op == "Flatten":
            ax = a.get("axis", 1)
            out = ins[0].reshape(int(np.prod(ins[0].shape[:ax])), -1)
        elif op == "Gemm":
            A = ins[0].T if a.get("transA", 0) else ins[0]
            B = ins[1].T if a.get("transB", 0) else ins[1]
            out = a.get("alpha", 1.0) * A @ B + (
                a.get("beta", 1.0) * ins[2] if len(ins) > 2 else 0.0
            )
        else:
            raise NotImplementedError(f"operator {op} is not in the reference evaluator")
        env[node.output[0]] = np.asarray(out)
    return env[g.output[0].name].reshape(len(x), -1)


def predict(path: str | Path, features: np.ndarray) -> np.ndarray:
    """(B, F) features -> (B, 2) metres: the metadata's normalisation around ``run_graph`` (module
    docstring of ``mission.localize.onnx_model``: network input (f - input_mean) / input_std, output
    o * std + mean)."""
    meta = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    norm = json.loads(meta["input_normalisation"])
    x = (np.atleast_2d(features) - np.asarray(norm["input_mean"])) / np.asarray(norm["input_std"])
    o = run_graph(path, x)[:, :2]
    return o * np.asarray(norm["output_std"]) + np.asarray(norm["output_mean"])
