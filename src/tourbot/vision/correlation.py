"""Local correlation of intensities (Burgard et al., Sec. 3): normalised cross-correlation of the
back-projected image ``î_t`` and the real image ``i_t`` in square windows, from box filters."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["local_ncc", "patch_ncc"]

Float32Array = NDArray[np.float32]


def local_ncc(
    a: Float32Array, b: Float32Array, window: int
) -> tuple[Float32Array, Float32Array, Float32Array]:
    """Per pixel: the NCC of ``a`` and ``b`` over the ``window`` x ``window`` neighbourhood, and
    both images' local standard deviations (texture: NCC means nothing on a blank wall)."""
    import cv2

    k = (window, window)
    a = a.astype(np.float32)
    b = b.astype(np.float32)
    ma = cv2.boxFilter(a, -1, k)
    mb = cv2.boxFilter(b, -1, k)
    va = np.maximum(cv2.boxFilter(a * a, -1, k) - ma * ma, 0.0)
    vb = np.maximum(cv2.boxFilter(b * b, -1, k) - mb * mb, 0.0)
    cov = cv2.boxFilter(a * b, -1, k) - ma * mb
    sa, sb = np.sqrt(va), np.sqrt(vb)
    ncc = cov / np.maximum(sa * sb, 1e-6)
    return ncc.astype(np.float32), sa.astype(np.float32), sb.astype(np.float32)


def patch_ncc(a: Float32Array, b: Float32Array) -> Float32Array:
    """NCC ``(M, K)`` of each patch ``a[m]`` ``(M, P)`` (flattened window) with the ``K``
    candidate patches ``b[m, k]`` ``(M, K, P)``."""
    p = a.shape[-1]
    da = a - a.mean(axis=-1, keepdims=True)
    num = np.einsum("mp,mkp->mk", da, b)  # da has zero mean: b's mean drops out
    sb = b.sum(axis=-1)
    vb = np.maximum(np.einsum("mkp,mkp->mk", b, b) - sb * sb / p, 0.0)
    va = (da * da).sum(axis=-1)[:, None]
    return np.asarray(num / np.maximum(np.sqrt(va * vb), 1e-6), dtype=np.float32)
