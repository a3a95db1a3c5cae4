"""Localizer networks (PyTorch; imported only by training, inference runs the exported ONNX).

Both networks are the paper's *RealAdaptRNet* family (Fig. "Proposed RealAdaptRNet architecture"): a
1D ResNet (Conv1D stem, residual blocks of kernel-3 / kernel-1 convolutions with batch norm, ReLU
and average pooling) followed by an MLP head of four fully connected layers down to the 2 outputs
(x, y).

- ``RealAdaptRNet`` on the 3D-clustering input (``3 C_k`` = 60 values): about 0.2 M parameters and
  about 1.3 M FLOPs, as in the paper.  The input is read as one channel of length ``3 C_k`` (the
  paper's layout); with ``triplet_stem=True`` the stem is a stride-3 convolution over each cluster's
  (p, x, y) triplet, which respects the feature's structure (one position per cluster) -- an option,
  not the default.
- ``NormalisedRssNet`` on the normalised-RSS baseline input (``S / N_g`` = 10 000 values): the same
  blocks with an extra pooling stage; about 6.7 M parameters and about 380 M FLOPs at the defaults
  (paper: 6.7 M / 332 M).

``count_parameters`` and ``count_flops`` (forward hooks on Conv1d / Linear / BatchNorm1d / pooling;
1 multiply-accumulate = 2 FLOPs, biases and ReLU not counted) report the complexity of either
network.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn


class ResBlock(nn.Module):
    """ResNet block "A": conv k3 (stride s) - BN - ReLU - conv k3 (stride 1) - BN, plus a shortcut
    (identity, or conv k1 stride s + BN when the shape changes), then ReLU."""

    def __init__(self, c_in: int, c_out: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv1d(c_in, c_out, 3, stride=stride, padding=1, bias=False)
        self.bn1 = nn.BatchNorm1d(c_out)
        self.conv2 = nn.Conv1d(c_out, c_out, 3, stride=1, padding=1, bias=False)
        self.bn2 = nn.BatchNorm1d(c_out)
        self.relu = nn.ReLU()
        self.short: nn.Module = nn.Identity()
        if stride != 1 or c_in != c_out:
            self.short = nn.Sequential(
                nn.Conv1d(c_in, c_out, 1, stride=stride, bias=False), nn.BatchNorm1d(c_out)
            )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.relu(self.bn1(self.conv1(x)))
        y = self.bn2(self.conv2(y))
        return self.relu(y + self.short(x))


def _mlp(n_in: int, hidden: Sequence[int], n_out: int = 2, dropout: float = 0.0) -> nn.Sequential:
    """Four fully connected layers (three hidden + output) progressively reducing the width."""
    layers: list[nn.Module] = []
    w = n_in
    for h in hidden:
        layers += [nn.Linear(w, h), nn.ReLU()]
        if dropout > 0:
            layers.append(nn.Dropout(dropout))
        w = h
    layers.append(nn.Linear(w, n_out))
    return nn.Sequential(*layers)


class _ConvHeadNet(nn.Module):
    """A 1D convolutional ``features`` stack followed by an MLP ``head`` to (x, y); shared by both
    networks."""

    features: nn.Sequential

    def _add_head(self, n_in: int, hidden: Sequence[int], dropout: float) -> None:
        """Size the MLP head from the flattened output of ``features`` on an input of length
        ``n_in``."""
        with torch.no_grad():
            n_flat = self.features(torch.zeros(1, 1, n_in)).numel()
        self.head = _mlp(n_flat, hidden, 2, dropout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.dim() == 2:
            x = x.unsqueeze(1)
        return self.head(torch.flatten(self.features(x), 1))


class RealAdaptRNet(_ConvHeadNet):
    """1D ResNet + 4-layer MLP on a 1-channel input of length ``n_in`` (default 60 = 3 C_k); outputs
    (B, 2).

    Stem conv(k3, s1, ``width``) - BN - ReLU; blocks (width, s1), (2 width, s2), (2 width, s1);
    average pooling by ``pool``; MLP ``hidden``.  Input (B, n_in) or (B, 1, n_in).
    """

    def __init__(
        self,
        n_in: int = 60,
        width: int = 16,
        pool: int = 2,
        hidden: Sequence[int] = (300, 128, 64),
        dropout: float = 0.1,
        triplet_stem: bool = False,
    ) -> None:
        super().__init__()
        self.n_in = n_in
        if triplet_stem:
            stem = nn.Conv1d(1, width, 3, stride=3, bias=False)
        else:
            stem = nn.Conv1d(1, width, 3, stride=1, padding=1, bias=False)
        self.features = nn.Sequential(
            stem,
            nn.BatchNorm1d(width),
            nn.ReLU(),
            ResBlock(width, width, 1),
            ResBlock(width, 2 * width, 2),
            ResBlock(2 * width, 2 * width, 1),
            nn.AvgPool1d(pool, ceil_mode=True),
        )
        self._add_head(n_in, hidden, dropout)


class NormalisedRssNet(_ConvHeadNet):
    """The normalised-RSS baseline: the same ResNet family on a long input (default 10 000 values).

    Stem conv(k3, ``width``); blocks (width, s1), (width, s1), pool 4, (2 width, s2), (2 width, s1),
    pool 4; MLP ``hidden``.  The width of the first MLP layer (flattened length x channels) makes up
    most of the parameters, as in the paper's 6.7 M.
    """

    def __init__(
        self,
        n_in: int = 10000,
        width: int = 32,
        hidden: Sequence[int] = (800, 256, 64),
        dropout: float = 0.1,
    ) -> None:
        super().__init__()
        self.n_in = n_in
        self.features = nn.Sequential(
            nn.Conv1d(1, width, 3, padding=1, bias=False),
            nn.BatchNorm1d(width),
            nn.ReLU(),
            ResBlock(width, width, 1),
            ResBlock(width, width, 1),
            nn.AvgPool1d(4, ceil_mode=True),
            ResBlock(width, 2 * width, 2),
            ResBlock(2 * width, 2 * width, 1),
            nn.AvgPool1d(10, ceil_mode=True),
        )
        self._add_head(n_in, hidden, dropout)


def build_net(kind: str, n_in: int, **kw) -> nn.Module:
    """The network for a feature kind: ``clustering`` -> RealAdaptRNet, ``normalised_rss`` ->
    baseline."""
    if kind == "clustering":
        return RealAdaptRNet(n_in, **kw)
    if kind == "normalised_rss":
        return NormalisedRssNet(n_in, **kw)
    raise ValueError(f"unknown feature kind {kind!r} (clustering or normalised_rss)")


def count_parameters(net: nn.Module) -> int:
    """Number of trainable parameters."""
    return int(sum(p.numel() for p in net.parameters() if p.requires_grad))


def count_flops(net: nn.Module, n_in: int) -> int:
    """Forward FLOPs of one sample (2 per multiply-accumulate) via forward hooks on the leaf layers.

    Conv1d: 2 * C_out * L_out * (C_in / groups) * k; Linear: 2 * in * out; BatchNorm1d (inference, a
    scale and shift): 2 * elements; AvgPool1d: elements in.  Biases and ReLU are not counted.
    """
    total = [0]

    def hook(mod: nn.Module, inp: tuple[torch.Tensor, ...], out: torch.Tensor) -> None:
        if isinstance(mod, nn.Conv1d):
            c_out, l_out = out.shape[1], out.shape[2]
            total[0] += 2 * c_out * l_out * (mod.in_channels // mod.groups) * mod.kernel_size[0]
        elif isinstance(mod, nn.Linear):
            total[0] += 2 * mod.in_features * mod.out_features
        elif isinstance(mod, nn.BatchNorm1d):
            total[0] += 2 * out[0].numel()
        elif isinstance(mod, nn.AvgPool1d):
            total[0] += inp[0][0].numel()

    handles = [
        m.register_forward_hook(hook)
        for m in net.modules()
        if isinstance(m, nn.Conv1d | nn.Linear | nn.BatchNorm1d | nn.AvgPool1d)
    ]
    was_training = net.training
    net.eval()
    try:
        with torch.no_grad():
            net(torch.zeros(1, n_in))
    finally:
        for h in handles:
            h.remove()
        net.train(was_training)
    return total[0]


class CoordinateWrapper(nn.Module):
    """The exported localizer: raw clustering features in, metres out, the parametrisation inside
    the graph.

    Input: raw features ``(B, F)`` (clustering: ``[p_1, x_1, y_1, ..., p_Ck, x_Ck, y_Ck]``, sorted
    by RSS descending, so cluster 1 is the strongest).  With ``relative=True`` (clustering only) the
    reference ``ref = (x_1, y_1)`` is subtracted from every cluster's (x, y); the result is
    standardised with the buffers ``in_mean`` / ``in_std`` (statistics of the *relative* training
    features), ``net`` runs, its output is de-standardised with ``out_mean`` / ``out_std``
    (statistics of ``truth - ref``) and ``ref`` is added back.  The graph is therefore exactly
    equivariant to a translation of the field: shifting every input (x, y) by (dx, dy) shifts the
    output by (dx, dy) (up to float32 rounding).  With ``relative=False`` ``ref`` is zero (absolute
    coordinates, the original parametrisation).

    Exported whole, so the ONNX metadata's ``input_normalisation`` is the identity (zeros / ones)
    and ``OnnxLocalizer`` feeds the raw features.
    """

    def __init__(
        self,
        net: nn.Module,
        in_mean: torch.Tensor,
        in_std: torch.Tensor,
        out_mean: torch.Tensor,
        out_std: torch.Tensor,
        relative: bool = True,
        n_in: int | None = None,
    ) -> None:
        super().__init__()
        self.net = net
        self.relative = bool(relative)
        self.n_in = int(n_in if n_in is not None else getattr(net, "n_in", in_mean.numel()))
        if self.relative and self.n_in % 3:
            raise ValueError("relative coordinates need clustering features (3 values per cluster)")
        self.register_buffer("in_mean", torch.as_tensor(in_mean, dtype=torch.float32).reshape(-1))
        self.register_buffer("in_std", torch.as_tensor(in_std, dtype=torch.float32).reshape(-1))
        self.register_buffer("out_mean", torch.as_tensor(out_mean, dtype=torch.float32).reshape(2))
        self.register_buffer("out_std", torch.as_tensor(out_std, dtype=torch.float32).reshape(2))

    def split(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Raw (B, F) -> (features in the network's frame (B, F), reference (B, 2); zeros when
        absolute)."""
        if x.dim() == 3:
            x = x.reshape(-1, self.n_in)
        if not self.relative:
            return x, torch.zeros_like(x[:, :2])
        v = x.reshape(-1, self.n_in // 3, 3)
        ref = v[:, 0, 1:3]
        shift = nn.functional.pad(ref, (1, 0)).unsqueeze(1)  # (B, 1, 3) = [0, x_1, y_1]
        return (v - shift).reshape(-1, self.n_in), ref

    def forward_standardised(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The network's standardised output (for the loss) and the reference it is relative to."""
        rel, ref = self.split(x)
        return self.net((rel - self.in_mean) / self.in_std), ref

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        z, ref = self.forward_standardised(x)
        return z * self.out_std + self.out_mean + ref
