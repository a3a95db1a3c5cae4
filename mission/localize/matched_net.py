"""A small numpy regression network: the learned summary of the track-matched localizer.

Why numpy: the network is trained after landing, inside ``localize``, on the flight's own simulated
transmitters, and ``localize`` must run on numpy (no torch at inference).  The net regresses the
transmitter position on the centred RSS-per-cell vector: its output approximates the posterior mean
E[x | RSS], the summary statistic of semi-automatic ABC (Fearnhead and Prangle 2012), from which
``matched`` draws the posterior.

Architecture: principal components of the inputs (``n_pca``, whitened; scikit-learn's ``PCA``) ->
``hidden`` ReLU layers -> 2 outputs, mean squared error on standardised targets, Adam with a
cosine-decayed step, mini-batches; all float32 and reproducible from the caller's generator.
The network itself stays numpy rather than scikit-learn's ``MLPRegressor``: that one has no decaying
step for Adam, trains in float64 (about twice the time of this float32 loop) and draws its
initialisation and batches from its own seed instead of the caller's generator.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from sklearn.decomposition import PCA

Progress = Callable[[str, int, int], None]


class Pca:
    """Mean and leading principal axes of a data set (scikit-learn's ``PCA``, fitted once, then
    ``transform``): each axis scaled to unit variance (``whiten``) or all by the first axis's spread
    (the weak, noisy axes stay small). The whitening is done here rather than by
    ``PCA(whiten=True)`` so that an axis of (near) zero variance is floored at 1e-9 of the first
    instead of dividing by zero."""

    def __init__(self, x: np.ndarray, n_components: int, whiten: bool = True) -> None:
        x = np.asarray(x, dtype=np.float64)
        k = int(min(n_components, x.shape[1], len(x)))
        self.pca = PCA(n_components=k, svd_solver="full").fit(x)
        self.variance = np.maximum(self.pca.explained_variance_, 0.0)
        top_var = max(float(self.variance.max()), 1e-12)
        self.scale = (
            np.sqrt(np.maximum(self.variance, 1e-9 * top_var))
            if whiten
            else np.full(k, np.sqrt(top_var))
        )

    def transform(self, x: np.ndarray) -> np.ndarray:
        z = self.pca.transform(np.asarray(x, dtype=np.float64)) / self.scale
        return z.astype(np.float32)


class SummaryNet:
    """MLP regression ``fit(X, Y, rng)`` / ``predict(X)`` (module docstring); Y (N, 2) positions in
    metres."""

    def __init__(
        self,
        n_pca: int = 64,
        hidden: tuple[int, ...] = (128, 128),
        epochs: int = 40,
        batch: int = 256,
        lr: float = 2e-3,
        weight_decay: float = 1e-4,
        whiten: bool = True,
    ) -> None:
        self.whiten = bool(whiten)
        self.n_pca = int(n_pca)
        self.hidden = tuple(int(h) for h in hidden)
        self.epochs = int(epochs)
        self.batch = int(batch)
        self.lr = float(lr)
        self.weight_decay = float(weight_decay)
        self.pca: Pca | None = None
        self.weights: list[np.ndarray] = []
        self.biases: list[np.ndarray] = []
        self.train_loss: list[float] = []

    def _forward(self, h: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        acts = [h]
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ w + b
            if i < last:
                h = np.maximum(h, 0.0)
            acts.append(h)
        return h, acts

    def fit(
        self,
        x: np.ndarray,
        y: np.ndarray,
        rng: np.random.Generator,
        progress: Progress | None = None,
        label: str = "training",
    ) -> SummaryNet:
        """Fit on inputs ``x`` (N, M) and targets ``y`` (N, 2); ``progress(label, epoch, epochs)``
        per epoch."""
        self.pca = Pca(x, self.n_pca, self.whiten)
        z = self.pca.transform(x)
        y = np.asarray(y, dtype=np.float64)
        self.y_mean, self.y_scale = y.mean(axis=0), np.maximum(y.std(axis=0), 1e-6)
        t = ((y - self.y_mean) / self.y_scale).astype(np.float32)
        sizes = (z.shape[1], *self.hidden, t.shape[1])
        self.weights = [
            (rng.standard_normal((a, b)) * np.sqrt(2.0 / a)).astype(np.float32)
            for a, b in zip(sizes[:-1], sizes[1:], strict=True)
        ]
        self.biases = [np.zeros(b, dtype=np.float32) for b in sizes[1:]]
        params = self.weights + self.biases
        m1 = [np.zeros_like(p) for p in params]
        m2 = [np.zeros_like(p) for p in params]
        b1, b2, eps = 0.9, 0.999, 1e-8
        n = len(z)
        nb = max(1, int(np.ceil(n / self.batch)))
        step = 0
        self.train_loss = []
        for ep in range(self.epochs):
            lr = self.lr * 0.5 * (1.0 + np.cos(np.pi * ep / self.epochs))
            perm = rng.permutation(n)
            tot = 0.0
            for bi in range(nb):
                idx = perm[bi * self.batch : (bi + 1) * self.batch]
                out, acts = self._forward(z[idx])
                g = out - t[idx]
                tot += float((g * g).sum())
                g *= 2.0 / len(idx)
                grads_w: list[np.ndarray] = []
                grads_b: list[np.ndarray] = []
                for i in range(len(self.weights) - 1, -1, -1):
                    grads_w.append(acts[i].T @ g + self.weight_decay * self.weights[i])
                    grads_b.append(g.sum(axis=0))
                    if i > 0:
                        g = (g @ self.weights[i].T) * (acts[i] > 0)
                grads = grads_w[::-1] + grads_b[::-1]
                step += 1
                c1, c2 = 1.0 - b1**step, 1.0 - b2**step
                for p, gr, a, v in zip(params, grads, m1, m2, strict=True):
                    a *= b1
                    a += (1.0 - b1) * gr
                    v *= b2
                    v += (1.0 - b2) * gr * gr
                    p -= (lr / c1) * a / (np.sqrt(v / c2) + eps)
            self.train_loss.append(tot / (n * t.shape[1]))
            if progress is not None:
                progress(label, ep + 1, self.epochs)
        return self

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Positions (N, 2) m for inputs (N, M) (or one input (M,) -> (2,))."""
        if self.pca is None:
            raise RuntimeError("SummaryNet.predict before fit")
        x = np.asarray(x)
        one = x.ndim == 1
        out, _ = self._forward(self.pca.transform(np.atleast_2d(x)))
        y = out.astype(np.float64) * self.y_scale + self.y_mean
        return y[0] if one else y
