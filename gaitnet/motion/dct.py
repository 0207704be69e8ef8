"""Orthonormal DCT-II along time, the temporal encoding of the motion predictor (thesis sec. 4.2.1).

For a trajectory ``x_1 … x_T`` of one node, thesis eq. (4.2) gives the ``l``-th coefficient

    C_l = sqrt(2/T) Σ_n x_n (1/sqrt(1 + δ_l1)) cos(π/(2T) (2n − 1)(l − 1)),

and eq. (4.3) its inverse. Written as a matrix with zero-based ``k = l − 1`` and ``i = n − 1``,

    D[k, i] = w_k cos(π (2i + 1) k / (2T)),   w_0 = sqrt(1/T),   w_k = sqrt(2/T) (k > 0),

so ``C = D x`` along time. ``D`` is orthogonal (``D Dᵀ = I``), hence the inverse (4.3) is
``Dᵀ``: :func:`idct_matrix` returns the transpose. ``D x`` equals
``scipy.fft.dct(x, type=2, norm="ortho")``. Keeping only the first ``L`` rows of ``D`` (and the
first ``L`` columns of ``Dᵀ``) drops the high temporal frequencies, as the thesis describes.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import torch

__all__ = ["dct_matrix", "dct_matrix_torch", "idct_matrix", "idct_matrix_torch"]


def dct_matrix(n: int, dtype: npt.DTypeLike = np.float64) -> np.ndarray:
    """The orthonormal DCT-II matrix ``D`` (n, n) of eq. (4.2): row ``k`` is frequency ``k``."""
    if int(n) != n or n < 1:
        raise ValueError(f"DCT length must be a positive integer, got {n!r}")
    n = int(n)
    k = np.arange(n, dtype=np.float64)[:, None]
    i = np.arange(n, dtype=np.float64)[None, :]
    D = np.cos(np.pi * (2.0 * i + 1.0) * k / (2.0 * n))
    D *= np.sqrt(2.0 / n)
    D[0] *= np.sqrt(0.5)
    return D.astype(dtype)


def idct_matrix(n: int, dtype: npt.DTypeLike = np.float64) -> np.ndarray:
    """The inverse transform of eq. (4.3), ``Dᵀ`` (n, n): ``x = Dᵀ C``."""
    return np.ascontiguousarray(dct_matrix(n, np.float64).T).astype(dtype)


def dct_matrix_torch(
    n: int, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
) -> torch.Tensor:
    """:func:`dct_matrix` as a torch tensor (computed in float64, then cast)."""
    return torch.from_numpy(dct_matrix(n)).to(dtype=dtype, device=device)


def idct_matrix_torch(
    n: int, dtype: torch.dtype = torch.float32, device: torch.device | str | None = None
) -> torch.Tensor:
    """:func:`idct_matrix` as a torch tensor (computed in float64, then cast)."""
    return torch.from_numpy(idct_matrix(n)).to(dtype=dtype, device=device)
