"""Best-fit rotations of 3×3 covariance matrices, batched: Horn's method (:mod:`arap.method.horn`) across SIMD lanes.

The cells are processed in blocks of :data:`BLOCK`, stored as a structure of arrays (one row per quantity, one
column per cell), and every step of Horn's method runs as a branch-free loop across the columns that the compiler
vectorises: the characteristic quartic of each cell, Newton steps on all unconverged cells together, the full
adjugate of ``N − λI`` with the eigenvector column picked by selects, the quaternion and the rotation. The cells that
need the careful path (zero covariance, a nearly repeated dominant eigenvalue) are redone one by one with
:func:`arap.method.horn.rotation_from_covariance`, so the result is the same rotation as the cell-by-cell method, which
equals the SVD recipe with the reflection fix.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from arap.errors import ArapError
from arap.kernels.parallel import policy
from arap.method.horn import _det3, rotation_from_covariance

# Scratch layout of a block of cells for :func:`rotations_block`.
BLOCK = 64
"""Cells per block of the batched kernels."""
ROW_S = 0
"""Rows 0–8: the covariance ``S`` (row-major)."""
ROW_LOWER = 9
"""Row 9: a lower bound of ``max_R tr(R S)`` (``-inf`` if none)."""
ROW_R = 10
"""Rows 10–18: the fitted rotation (row-major)."""
ROW_TRACE = 19
"""Row 19: the optimum ``tr(R S)``."""
_ROW_LAM = 20
_ROW_C2 = 21
_ROW_C1 = 22
_ROW_C0 = 23
_ROW_UPPER = 24
SCRATCH_ROWS = 25


@nb.njit(cache=True, nogil=True, inline="always")
def put_covariance(sc: np.ndarray, t: int, s: tuple, R: np.ndarray, c: int) -> None:  # pragma: no cover - compiled
    """Column ``t`` of a scratch block: the covariance ``s`` (9 values, row-major) and the lower bound ``tr(R_c s)``
    of the optimum from the cell's previous rotation (``-inf`` if not finite), which makes the fit converge in few
    steps."""
    for i in range(9):
        sc[i * BLOCK + t] = s[i]
    lower = (R[c, 0, 0] * s[0] + R[c, 0, 1] * s[3] + R[c, 0, 2] * s[6] + R[c, 1, 0] * s[1] + R[c, 1, 1] * s[4]
             + R[c, 1, 2] * s[7] + R[c, 2, 0] * s[2] + R[c, 2, 1] * s[5] + R[c, 2, 2] * s[8])
    if not (lower > -np.inf and lower < np.inf):
        lower = -np.inf
    sc[ROW_LOWER * BLOCK + t] = lower


@nb.njit(cache=True, nogil=True, inline="always")
def take_rotation(sc: np.ndarray, t: int, R: np.ndarray, c: int) -> None:  # pragma: no cover - compiled
    """``R[c]`` from the fitted rotation in column ``t`` of a scratch block."""
    for i in range(3):
        for j in range(3):
            R[c, i, j] = sc[(ROW_R + 3 * i + j) * BLOCK + t]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def rotations_block(sc: np.ndarray, m: int, flag: np.ndarray) -> None:  # pragma: no cover - compiled
    """Best-fit rotations of the ``m`` covariances in the columns of the scratch block ``sc``, in place.

    The same method as :func:`rotation_from_covariance`, arranged as branch-free loops across cells (SIMD): the
    characteristic quartic of every cell, Newton steps on all unconverged cells together, and the eigenvector from
    the full adjugate of ``N − λI`` with the column chosen by selects. Cells that need the careful path (zero
    covariance, a (nearly) repeated dominant eigenvalue) are redone one by one with :func:`rotation_from_covariance`.

    Parameters
    ----------
    sc : (SCRATCH_ROWS * BLOCK,) float64 array
        Row ``r`` of the block is ``sc[r * BLOCK : (r + 1) * BLOCK]`` (flat, so that the compiler sees the rows do not
        overlap and vectorises). Rows ``ROW_S…ROW_S+8`` and ``ROW_LOWER`` in; rows ``ROW_R…ROW_R+8`` and ``ROW_TRACE``
        out; the other rows are work space.
    m : int
        Number of columns (cells) in use.
    flag : (BLOCK,) int64 array
        Work space.
    """
    for c in range(m):
        sxx = sc[c]
        sxy = sc[BLOCK + c]
        sxz = sc[2 * BLOCK + c]
        syx = sc[3 * BLOCK + c]
        syy = sc[4 * BLOCK + c]
        syz = sc[5 * BLOCK + c]
        szx = sc[6 * BLOCK + c]
        szy = sc[7 * BLOCK + c]
        szz = sc[8 * BLOCK + c]
        fro2 = (sxx * sxx + sxy * sxy + sxz * sxz + syx * syx + syy * syy + syz * syz
                + szx * szx + szy * szy + szz * szz)
        n00 = sxx + syy + szz
        n01 = syz - szy
        n02 = szx - sxz
        n03 = sxy - syx
        n11 = sxx - syy - szz
        n12 = sxy + syx
        n13 = szx + sxz
        n22 = -sxx + syy - szz
        n23 = syz + szy
        n33 = -sxx - syy + szz
        s0 = n00 * n11 - n01 * n01
        s1 = n00 * n12 - n02 * n01
        s2 = n00 * n13 - n03 * n01
        s3 = n01 * n12 - n02 * n11
        s4 = n01 * n13 - n03 * n11
        s5 = n02 * n13 - n03 * n12
        k5 = n22 * n33 - n23 * n23
        k4 = n12 * n33 - n13 * n23
        k3 = n12 * n23 - n13 * n22
        k2 = n02 * n33 - n03 * n23
        k1 = n02 * n23 - n03 * n22
        k0 = n02 * n13 - n03 * n12
        upper = math.sqrt(3.0 * fro2)
        lower = sc[ROW_LOWER * BLOCK + c]
        sc[_ROW_LAM * BLOCK + c] = lower if lower > 0.5 * upper else upper
        sc[_ROW_C2 * BLOCK + c] = -2.0 * fro2
        sc[_ROW_C1 * BLOCK + c] = -8.0 * _det3(sxx, sxy, sxz, syx, syy, syz, szx, szy, szz)
        sc[_ROW_C0 * BLOCK + c] = s0 * k5 - s1 * k4 + s2 * k3 + s3 * k2 - s4 * k1 + s5 * k0
        sc[_ROW_UPPER * BLOCK + c] = upper
        flag[c] = 0 if fro2 > 0.0 else 1
    # Newton on the quartic for all cells at once; converged cells keep their root (see rotation_from_covariance).
    for _ in range(80):
        running = 0
        for c in range(m):
            lam = sc[_ROW_LAM * BLOCK + c]
            c2 = sc[_ROW_C2 * BLOCK + c]
            c1 = sc[_ROW_C1 * BLOCK + c]
            upper = sc[_ROW_UPPER * BLOCK + c]
            lam2 = lam * lam
            p = (lam2 + c2) * lam2 + c1 * lam + sc[_ROW_C0 * BLOCK + c]
            dp = (4.0 * lam2 + 2.0 * c2) * lam + c1
            bad = not dp > 0.0 or lam > upper
            step = p / dp
            stop = (lam == upper) if bad else (abs(step) <= 1e-15 * upper)
            was = flag[c]
            nxt = upper if bad else lam - step
            sc[_ROW_LAM * BLOCK + c] = lam if was else nxt
            now = 1 if (was or stop) else 0
            flag[c] = now
            running += 1 - now
        if running == 0:
            break
    careful = 0
    for c in range(m):
        sxx = sc[c]
        sxy = sc[BLOCK + c]
        sxz = sc[2 * BLOCK + c]
        syx = sc[3 * BLOCK + c]
        syy = sc[4 * BLOCK + c]
        syz = sc[5 * BLOCK + c]
        szx = sc[6 * BLOCK + c]
        szy = sc[7 * BLOCK + c]
        szz = sc[8 * BLOCK + c]
        lam = sc[_ROW_LAM * BLOCK + c]
        upper = sc[_ROW_UPPER * BLOCK + c]
        # A = N − λI (symmetric); its adjugate from the 2×2 minors of rows 0–1 (t..) and rows 2–3 (b..).
        a00 = sxx + syy + szz - lam
        a01 = syz - szy
        a02 = szx - sxz
        a03 = sxy - syx
        a11 = sxx - syy - szz - lam
        a12 = sxy + syx
        a13 = szx + sxz
        a22 = -sxx + syy - szz - lam
        a23 = syz + szy
        a33 = -sxx - syy + szz - lam
        b01 = a02 * a13 - a12 * a03
        b02 = a02 * a23 - a22 * a03
        b03 = a02 * a33 - a23 * a03
        b12 = a12 * a23 - a22 * a13
        b13 = a12 * a33 - a23 * a13
        b23 = a22 * a33 - a23 * a23
        t01 = a00 * a11 - a01 * a01
        t02 = a00 * a12 - a02 * a01
        t03 = a00 * a13 - a03 * a01
        t12 = a01 * a12 - a02 * a11
        t13 = a01 * a13 - a03 * a11
        d0 = a11 * b23 - a12 * b13 + a13 * b12
        d1 = a00 * b23 - a02 * b03 + a03 * b02
        d2 = a03 * t13 - a13 * t03 + a33 * t01
        d3 = a02 * t12 - a12 * t02 + a22 * t01
        e01 = a12 * b03 - a01 * b23 - a13 * b02
        e02 = a01 * b13 - a11 * b03 + a13 * b01
        e03 = a11 * b02 - a01 * b12 - a12 * b01
        e12 = a01 * b03 - a00 * b13 - a03 * b01
        e13 = a00 * b12 - a01 * b02 + a02 * b01
        e23 = a13 * t02 - a03 * t12 - a23 * t01
        # The column of the largest diagonal cofactor (first one on ties, as in rotation_from_covariance).
        qw = d0
        qx = e01
        qy = e02
        qz = e03
        dmax = abs(d0)
        if abs(d1) > dmax:
            qw = e01
            qx = d1
            qy = e12
            qz = e13
            dmax = abs(d1)
        if abs(d2) > dmax:
            qw = e02
            qx = e12
            qy = d2
            qz = e23
            dmax = abs(d2)
        if abs(d3) > dmax:
            qw = e03
            qx = e13
            qy = e23
            qz = d3
            dmax = abs(d3)
        weak = not dmax > 1e-9 * upper * upper * upper
        inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        qw *= inv
        qx *= inv
        qy *= inv
        qz *= inv
        r00 = qw * qw + qx * qx - qy * qy - qz * qz
        r01 = 2.0 * (qx * qy - qw * qz)
        r02 = 2.0 * (qx * qz + qw * qy)
        r10 = 2.0 * (qx * qy + qw * qz)
        r11 = qw * qw - qx * qx + qy * qy - qz * qz
        r12 = 2.0 * (qy * qz - qw * qx)
        r20 = 2.0 * (qx * qz - qw * qy)
        r21 = 2.0 * (qy * qz + qw * qx)
        r22 = qw * qw - qx * qx - qy * qy + qz * qz
        sc[ROW_R * BLOCK + c] = r00
        sc[(ROW_R + 1) * BLOCK + c] = r01
        sc[(ROW_R + 2) * BLOCK + c] = r02
        sc[(ROW_R + 3) * BLOCK + c] = r10
        sc[(ROW_R + 4) * BLOCK + c] = r11
        sc[(ROW_R + 5) * BLOCK + c] = r12
        sc[(ROW_R + 6) * BLOCK + c] = r20
        sc[(ROW_R + 7) * BLOCK + c] = r21
        sc[(ROW_R + 8) * BLOCK + c] = r22
        sc[ROW_TRACE * BLOCK + c] = (r00 * sxx + r01 * syx + r02 * szx + r10 * sxy + r11 * syy + r12 * szy
                            + r20 * sxz + r21 * syz + r22 * szz)
        flag[c] = 1 if weak else 0
        careful += 1 if weak else 0
    if careful:
        R = np.empty((3, 3))
        for c in range(m):
            if flag[c]:
                sc[ROW_TRACE * BLOCK + c] = rotation_from_covariance(
                    sc[c], sc[BLOCK + c], sc[2 * BLOCK + c], sc[3 * BLOCK + c], sc[4 * BLOCK + c],
                    sc[5 * BLOCK + c], sc[6 * BLOCK + c], sc[7 * BLOCK + c], sc[8 * BLOCK + c],
                    sc[ROW_LOWER * BLOCK + c], R)
                for i in range(3):
                    for jj in range(3):
                        sc[(ROW_R + 3 * i + jj) * BLOCK + c] = R[i, jj]


@nb.njit(cache=True, nogil=True)
def _fit_chunk(ch: int, S: np.ndarray, R: np.ndarray) -> None:  # pragma: no cover - compiled
    k = S.shape[0]
    sc = np.empty(SCRATCH_ROWS * BLOCK)
    flag = np.empty(BLOCK, np.int64)
    for lo in range(ch * _FIT_CHUNK * BLOCK, min(k, (ch + 1) * _FIT_CHUNK * BLOCK), BLOCK):
        m = min(k, lo + BLOCK) - lo
        for t in range(m):
            for i in range(3):
                for j in range(3):
                    sc[(ROW_S + 3 * i + j) * BLOCK + t] = S[lo + t, i, j]
            sc[ROW_LOWER * BLOCK + t] = -np.inf
        rotations_block(sc, m, flag)
        for t in range(m):
            for i in range(3):
                for j in range(3):
                    R[lo + t, i, j] = sc[(ROW_R + 3 * i + j) * BLOCK + t]


_FIT_CHUNK = 8


@nb.njit(cache=True, nogil=True)
def _fit_serial(S: np.ndarray, R: np.ndarray) -> None:  # pragma: no cover - compiled
    for ch in range((S.shape[0] + _FIT_CHUNK * BLOCK - 1) // (_FIT_CHUNK * BLOCK)):
        _fit_chunk(ch, S, R)


@nb.njit(cache=True, nogil=True, parallel=True)
def _fit_parallel(S: np.ndarray, R: np.ndarray) -> None:  # pragma: no cover - compiled
    for ch in nb.prange((S.shape[0] + _FIT_CHUNK * BLOCK - 1) // (_FIT_CHUNK * BLOCK)):
        _fit_chunk(ch, S, R)


def identity_rotations(n: int) -> np.ndarray:
    """``n`` identity matrices, shape (n, 3, 3): the start of a rotation fit without previous rotations.

    The fits (:func:`arap.method.local_step.local_step`) start their root search from the previous rotation of each
    cell; any start converges, but to last bits that depend on it, so a fixed start keeps results reproducible (an
    uninitialised array would not).

    Example
    -------
    >>> identity_rotations(2).shape
    (2, 3, 3)
    """
    return np.broadcast_to(np.eye(3), (n, 3, 3)).copy()


def rotations_from_covariances(S: np.ndarray) -> np.ndarray:
    """Best-fit rotations of a stack of 3×3 (cell covariance) matrices.

    Parameters
    ----------
    S : (k, 3, 3) float array
        Cell covariance matrices ``Σ_j w_j e_j e'_jᵀ``.

    Returns
    -------
    (k, 3, 3) float64 array
        ``R[i]`` maximises ``tr(R[i] S[i])`` over rotations (det = +1).

    Examples
    --------
    The covariance of a quarter turn about z gives that turn back:

    >>> import numpy as np, arap
    >>> R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    >>> P = np.random.default_rng(0).normal(size=(5, 3))
    >>> S = (P.T @ (P @ R.T))[None]                            # sum of p (R p)^T over the points
    >>> bool(np.allclose(arap.rotations_from_covariances(S)[0], R))
    True
    """
    S = np.ascontiguousarray(S, dtype=np.float64)
    if S.ndim != 3 or S.shape[1:] != (3, 3):
        raise ArapError(f"expected a (k, 3, 3) stack of matrices, got shape {S.shape}")
    R = np.empty_like(S)
    # About 20 operations per matrix entry: weigh a matrix like two edge terms of a cell.
    policy.run("fit_rotations", 2 * len(S), lambda: _fit_serial(S, R), lambda: _fit_parallel(S, R))
    return R
