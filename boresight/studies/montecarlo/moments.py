"""Streamed, mergeable moments of θ̂ − θ (Chan et al. parallel combination)."""

from __future__ import annotations

import numpy as np

from boresight.errors import InputValueError


class Moments:
    """Mergeable running moments of samples along a leading axis (count, mean, M2, max |x|).

    ``merge`` is the parallel combination of Chan, Golub & LeVeque (1979):
    δ = m_b − m_a, m = m_a + δ n_b/n, M2 = M2_a + M2_b + δ² n_a n_b/n. The block statistics
    come from a two-pass sum over the block's samples; merging in a fixed (block) order
    makes the result independent of how the samples were chunked.

    >>> a = Moments.from_samples(np.array([[1.0], [2.0]]))
    >>> b = Moments.from_samples(np.array([[3.0], [4.0], [5.0]]))
    >>> m = a.merge(b)
    >>> float(m.mean[0]), float(m.std[0]) == float(np.std([1, 2, 3, 4, 5], ddof=1)), float(m.max_abs[0])
    (3.0, True, 5.0)
    """

    __slots__ = ("count", "mean", "m2", "max_abs")

    def __init__(self, count, mean, m2, max_abs):
        self.count = int(count)
        self.mean = np.asarray(mean, float)
        self.m2 = np.asarray(m2, float)
        self.max_abs = np.asarray(max_abs, float)

    @classmethod
    def from_samples(cls, x) -> "Moments":
        """Moments of ``x`` (K, ...) over its first axis (K ≥ 1)."""
        x = np.asarray(x, float)
        if x.ndim < 1 or x.shape[0] < 1:
            raise InputValueError(f"Moments.from_samples: expected shape (K ≥ 1, ...), got {x.shape}")
        mean = x.mean(axis=0)
        d = x - mean
        return cls(x.shape[0], mean, np.einsum("k...,k...->...", d, d), np.abs(x).max(axis=0))

    def merge(self, other: "Moments") -> "Moments":
        """The moments of the union of the two sample sets."""
        n = self.count + other.count
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.count / n)
        m2 = self.m2 + other.m2 + delta * delta * (self.count * other.count / n)
        return Moments(n, mean, m2, np.maximum(self.max_abs, other.max_abs))

    @property
    def variance(self) -> np.ndarray:
        """Sample variance, ddof = 1 (Kiev 2012's D̃)."""
        if self.count < 2:
            raise InputValueError(f"Moments.variance needs ≥ 2 samples, got {self.count}")
        return self.m2 / (self.count - 1)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(self.variance)

    def __eq__(self, other):
        return (
            isinstance(other, Moments)
            and self.count == other.count
            and all(np.array_equal(getattr(self, k), getattr(other, k)) for k in ("mean", "m2", "max_abs"))
        )
