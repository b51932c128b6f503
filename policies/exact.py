"""Matrix products and tanh whose bits do not depend on the CPU, the BLAS library or numpy's
SIMD dispatch: what makes a learned policy's episodes the same on every machine.

A float32 ``x @ w`` goes through BLAS, and OpenBLAS picks its kernel by CPU (Haswell,
SkylakeX, ...): each kernel adds the products in another order, the last bits differ, and a
flock's dynamics amplify them (``boids run --policy learned`` gave V_sep 1.1877, 1.0550 or
0.9330 by kernel). ``np.tanh`` and ``np.exp`` also have per-CPU SIMD versions that round
differently. Here:

- **Products are exact.** Each row of ``x`` is cut into two slices of integers below 2^16
  times a power of two (its largest element sets the power), each weight column into integers
  below ``2^w_bits`` times a power of two, with ``16 + w_bits + log2(K) <= 53`` for ``K``
  inputs. Every product of two such integers and every partial sum of ``K`` of them is an
  integer below 2^53, which float64 holds exactly, so the float64 matrix product of the
  integer arrays is exact in *any* order and with or without fused multiply-adds: every BLAS
  kernel on every CPU returns the same bits. Scaling by powers of two is exact too; the one
  rounding left (adding the two slices' products) is an elementwise float64 add, the same
  everywhere. The price: two float64 products instead of one float32 product, and the inputs
  are kept to 32 bits below each row's largest element, the weights to ``w_bits`` (30 for 128
  inputs) below each column's largest: errors of ~1e-9 relative, far below float32's 6e-8.
- **tanh is computed from + - * / alone** (correctly rounded in IEEE 754 on every CPU, SIMD
  or not): ``exp`` by range reduction and a Padé approximant (relative error below 3e-12),
  then ``(1 - e^-2|y|) / (1 + e^-2|y|)`` with the sign of ``y``.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

SLICE_BITS = 16
"""Bits of each of the two integer slices of an input row (32 bits in all)."""
MANTISSA_BITS = 53
"""float64 holds every integer up to 2^53 exactly."""
_SLICE = float(2**SLICE_BITS)
SINGLE_THREAD_PRODUCT = 262_144
"""Multiply-adds per matrix product call: OpenBLAS (numpy's BLAS) runs a product of at most
this many on one thread. Larger ones it splits over threads, which spin while they wait: with
eval workers on every core, or other programs, a learned suite ran 3x slower. A few small
calls cost little, and the result is the same (exact) however the rows are grouped."""


def weight_bits(inputs: int) -> int:
    """Bits a weight column keeps for ``inputs`` inputs: the most for which a sum of
    ``inputs`` products of a slice (< 2^16) and a weight integer stays below 2^53."""
    if inputs < 1:
        raise ValueError(f"a layer needs at least one input, got {inputs}")
    return MANTISSA_BITS - SLICE_BITS - math.ceil(math.log2(inputs))


def _exponents(values: npt.NDArray[np.float64], axis: int) -> npt.NDArray[np.int32]:
    """Per row (``axis=1``) or column (``axis=0``): ``E`` with every ``|value| < 2^E``."""
    return np.frexp(np.max(np.abs(values), axis=axis, keepdims=True))[1]


class ExactLinear:
    """``x @ w + b`` with the product computed exactly (see the module's docstring); the
    result is rounded once per slice sum and once for the bias, elementwise.

    Args:
        weight: (K, H) matrix (inputs × outputs), any float dtype.
        bias: (H,) vector.
    """

    def __init__(self, weight: npt.ArrayLike, bias: npt.ArrayLike) -> None:
        w = np.asarray(weight, dtype=np.float64)
        if w.ndim != 2 or not np.isfinite(w).all():
            raise ValueError(f"weight must be a finite (inputs, outputs) matrix, got shape "
                             f"{w.shape}")
        self.w_bits = weight_bits(w.shape[0])
        exponents = _exponents(w, axis=0)  # (1, H)
        # integers |q| <= 2^w_bits; w = q * 2^(E - w_bits) up to w_bits bits of each column
        self.q = np.rint(np.ldexp(w, self.w_bits - exponents))
        # (1, H) powers of two: the column's, and the rows' slices' 2^-16
        self.column_scale = np.ldexp(1.0, exponents - self.w_bits - SLICE_BITS)
        self.bias = np.asarray(bias, dtype=np.float64)
        self.rows_per_call = max(1, SINGLE_THREAD_PRODUCT // w.size)

    def products(self, slices: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The integer slices' rows (R, K) times the weight integers: one product for both
        slices (rows stacked), exact in any summation order, since every partial sum is an
        integer below 2^53; at most :data:`SINGLE_THREAD_PRODUCT` multiply-adds a call."""
        both = np.empty((len(slices), self.q.shape[1]))
        for start in range(0, len(slices), self.rows_per_call):
            end = start + self.rows_per_call
            np.matmul(slices[start:end], self.q, out=both[start:end])
        return both

    def __call__(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """``x @ w + b`` for ``x`` (F, K) float64."""
        n = len(x)
        rows = _exponents(x, axis=1)  # (F, 1): every |x| < 2^rows
        slices = np.empty((2 * n, x.shape[1]))
        scaled = np.ldexp(x, SLICE_BITS - rows)  # exact, |scaled| < 2^16
        high = np.rint(scaled, out=slices[:n])  # |high| <= 2^16
        # scaled - high is exact (a float minus its nearest integer); |low| <= 2^15
        np.subtract(scaled, high, out=scaled)
        np.rint(np.multiply(scaled, _SLICE, out=scaled), out=slices[n:])
        both = self.products(slices)
        total = np.add(both[:n], np.multiply(both[n:], 1.0 / _SLICE, out=both[n:]))
        # the row's and the column's powers of two (exact), then the bias (one rounding)
        np.multiply(np.ldexp(total, rows, out=total), self.column_scale, out=total)
        return np.add(total, self.bias, out=total)


INV_LN2 = 1.0 / math.log(2.0)
LN2 = math.log(2.0)
TANH_ONE = 20.0
"""|y| from which tanh(y) rounds to ±1 in float64 (1 - tanh(20) = 8e-18 < 2^-53)."""


def tanh(y: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """tanh of a float64 array from + - * / and exact scalings alone: the same bits on every
    CPU (``np.tanh`` is not: its SIMD versions round differently). Absolute error below
    2e-12.

    ``e = exp(-2|y|) = 2^k exp(r)`` with ``|r| <= ln2 / 2`` and ``exp(r)`` as its [4/4] Padé
    approximant ``N / D`` (relative error below 3e-12); then ``tanh|y| = (1 - e) / (1 + e)
    = (D - 2^k N) / (D + 2^k N)``, given the sign of ``y``.
    """
    t = np.minimum(np.abs(y), TANH_ONE)
    z = t * -2.0  # z in [-40, 0]
    # z = k ln2 + r; fmax turns a NaN's k into a number (a NaN y still gives NaN, through r)
    # so the cast to int below never sees one
    k = np.rint(np.fmax(z * INV_LN2, -64.0))
    r = z - k * LN2
    r2 = r * r
    even = (r2 * (1.0 / 1680.0) + 3.0 / 28.0) * r2 + 1.0  # the Padé polynomials' even part
    odd = (r2 * (1.0 / 84.0) + 0.5) * r  # and odd part: N = even + odd, D = even - odd
    scaled = np.ldexp(even + odd, k.astype(np.int32))
    den = even - odd
    return np.copysign((den - scaled) / (den + scaled), y)


def relu(y: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """max(y, 0) (exact everywhere)."""
    return np.maximum(y, 0.0)
