"""Best-fit rotations of 3×3 covariance matrices, one per cell, batched.

For a cell covariance ``S = Σ_j w_j e_j e'_jᵀ`` (rest edge ``e``, deformed edge ``e'``) the local step of ARAP
(Sorkine & Alexa 2007) needs the rotation ``R`` maximising ``tr(R S)``. The textbook answer is ``R = V Uᵀ`` from the
SVD ``S = U Σ Vᵀ``, with the column of ``U`` of the smallest singular value negated when ``det(V Uᵀ) < 0``.

The batched kernel here computes the same rotation with Horn's quaternion method (Horn 1987): the optimal rotation
is the unit quaternion that is the dominant eigenvector of a symmetric, traceless 4×4 matrix ``N(S)``; its largest
eigenvalue is found by Newton's method on the characteristic quartic started above the root (as in Theobald's QCP,
2005), and the eigenvector is read off the adjugate of ``N − λI``. The reflection case needs no special branch: the
quaternion is always a proper rotation, and it is the one the SVD recipe gives. When the dominant eigenvalue is
(nearly) repeated, the optimum is not unique and a cyclic Jacobi eigen-solver picks one.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from arap._parallel import policy


@nb.njit(cache=True, fastmath=False, inline="always")
def _det3(a00: float, a01: float, a02: float, a10: float, a11: float, a12: float, a20: float, a21: float,
          a22: float) -> float:
    return a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20)


@nb.njit(cache=True)
def _jacobi_dominant(N: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Eigenvector of the largest eigenvalue of a symmetric 4×4 matrix by cyclic Jacobi rotations."""
    A = N.copy()
    Q = np.eye(4)
    for _sweep in range(50):
        off = 0.0
        for p in range(4):
            for q in range(p + 1, 4):
                off += A[p, q] * A[p, q]
        if off < 1e-30 * (A[0, 0] ** 2 + A[1, 1] ** 2 + A[2, 2] ** 2 + A[3, 3] ** 2 + 1e-300):
            break
        for p in range(4):
            for q in range(p + 1, 4):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(4):
                    akp = A[k, p]
                    akq = A[k, q]
                    A[k, p] = c * akp - s * akq
                    A[k, q] = s * akp + c * akq
                for k in range(4):
                    apk = A[p, k]
                    aqk = A[q, k]
                    A[p, k] = c * apk - s * aqk
                    A[q, k] = s * apk + c * aqk
                for k in range(4):
                    qkp = Q[k, p]
                    qkq = Q[k, q]
                    Q[k, p] = c * qkp - s * qkq
                    Q[k, q] = s * qkp + c * qkq
    best = 0
    for k in range(1, 4):
        if A[k, k] > A[best, best]:
            best = k
    return Q[:, best].copy()


@nb.njit(cache=True)
def best_rotation(S: np.ndarray, R: np.ndarray) -> None:  # pragma: no cover - compiled
    """Write into ``R`` (3×3) the rotation maximising ``tr(R S)`` for one 3×3 matrix ``S``."""
    rotation_from_covariance(S[0, 0], S[0, 1], S[0, 2], S[1, 0], S[1, 1], S[1, 2], S[2, 0], S[2, 1], S[2, 2],
                             -np.inf, R)


@nb.njit(cache=True)
def rotation_from_covariance(sxx: float, sxy: float, sxz: float, syx: float, syy: float, syz: float, szx: float,
                             szy: float, szz: float, lower: float, R: np.ndarray) -> float:  # pragma: no cover
    """Best-fit rotation of the covariance given by its nine entries, written into ``R`` (3×3).

    ``lower`` is a known lower bound of the optimum ``max_R tr(R S)`` (e.g. ``tr(R_prev S)`` for the previous
    rotation, or ``-inf``); a tight one saves Newton steps. Returns the optimum ``tr(R S)``.
    """
    fro2 = (sxx * sxx + sxy * sxy + sxz * sxz + syx * syx + syy * syy + syz * syz
            + szx * szx + szy * szy + szz * szz)
    if not fro2 > 0.0:
        for i in range(3):
            for j in range(3):
                R[i, j] = 1.0 if i == j else 0.0
        return 0.0
    # Horn's symmetric matrix N (10 distinct entries).
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
    # Characteristic polynomial λ⁴ + c2 λ² + c1 λ + c0 (N is traceless).
    c2 = -2.0 * fro2
    c1 = -8.0 * _det3(sxx, sxy, sxz, syx, syy, syz, szx, szy, szz)
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
    c0 = s0 * k5 - s1 * k4 + s2 * k3 + s3 * k2 - s4 * k1 + s5 * k0
    # Newton on the quartic. From above the largest root (σ1+σ2+σ3 ≤ √3‖S‖_F) it converges monotonically; from a
    # tight lower bound it lands above the root in one step and then converges as well. Should a step from the lower
    # bound go astray (flat or wrong-signed slope), restart from the upper bound.
    upper = math.sqrt(3.0 * fro2)
    scale = upper
    lam = lower if lower > 0.5 * upper else upper
    for _ in range(80):
        lam2 = lam * lam
        p = (lam2 + c2) * lam2 + c1 * lam + c0
        dp = (4.0 * lam2 + 2.0 * c2) * lam + c1
        if dp <= 0.0 or lam > upper:
            if lam == upper:
                break
            lam = upper
            continue
        step = p / dp
        lam -= step
        if abs(step) <= 1e-15 * scale:
            break
    # Adjugate of A = N - λI: pick the column with the largest diagonal cofactor.
    a00 = n00 - lam
    a11 = n11 - lam
    a22 = n22 - lam
    a33 = n33 - lam
    d0 = _det3(a11, n12, n13, n12, a22, n23, n13, n23, a33)
    d1 = _det3(a00, n02, n03, n02, a22, n23, n03, n23, a33)
    d2 = _det3(a00, n01, n03, n01, a11, n13, n03, n13, a33)
    d3 = _det3(a00, n01, n02, n01, a11, n12, n02, n12, a22)
    ad0, ad1, ad2, ad3 = abs(d0), abs(d1), abs(d2), abs(d3)
    best = 0
    dmax = ad0
    if ad1 > dmax:
        best, dmax = 1, ad1
    if ad2 > dmax:
        best, dmax = 2, ad2
    if ad3 > dmax:
        best, dmax = 3, ad3
    if dmax > 1e-9 * scale * scale * scale:
        if best == 0:
            qw = d0
            qx = -_det3(n01, n12, n13, n02, a22, n23, n03, n23, a33)
            qy = _det3(n01, a11, n13, n02, n12, n23, n03, n13, a33)
            qz = -_det3(n01, a11, n12, n02, n12, a22, n03, n13, n23)
        elif best == 1:
            qw = -_det3(n01, n02, n03, n12, a22, n23, n13, n23, a33)
            qx = d1
            qy = -_det3(a00, n01, n03, n02, n12, n23, n03, n13, a33)
            qz = _det3(a00, n01, n02, n02, n12, a22, n03, n13, n23)
        elif best == 2:
            qw = _det3(n01, n02, n03, a11, n12, n13, n13, n23, a33)
            qx = -_det3(a00, n02, n03, n01, n12, n13, n03, n23, a33)
            qy = d2
            qz = -_det3(a00, n01, n02, n01, a11, n12, n03, n13, n23)
        else:
            qw = -_det3(n01, n02, n03, a11, n12, n13, n12, a22, n23)
            qx = _det3(a00, n02, n03, n01, n12, n13, n02, a22, n23)
            qy = -_det3(a00, n01, n03, n01, a11, n13, n02, n12, n23)
            qz = d3
    else:
        N = np.empty((4, 4))
        N[0, 0], N[0, 1], N[0, 2], N[0, 3] = n00, n01, n02, n03
        N[1, 0], N[1, 1], N[1, 2], N[1, 3] = n01, n11, n12, n13
        N[2, 0], N[2, 1], N[2, 2], N[2, 3] = n02, n12, n22, n23
        N[3, 0], N[3, 1], N[3, 2], N[3, 3] = n03, n13, n23, n33
        q = _jacobi_dominant(N)
        qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    qw *= inv
    qx *= inv
    qy *= inv
    qz *= inv
    R[0, 0] = qw * qw + qx * qx - qy * qy - qz * qz
    R[0, 1] = 2.0 * (qx * qy - qw * qz)
    R[0, 2] = 2.0 * (qx * qz + qw * qy)
    R[1, 0] = 2.0 * (qx * qy + qw * qz)
    R[1, 1] = qw * qw - qx * qx + qy * qy - qz * qz
    R[1, 2] = 2.0 * (qy * qz - qw * qx)
    R[2, 0] = 2.0 * (qx * qz - qw * qy)
    R[2, 1] = 2.0 * (qy * qz + qw * qx)
    R[2, 2] = qw * qw - qx * qx - qy * qy + qz * qz
    return (R[0, 0] * sxx + R[0, 1] * syx + R[0, 2] * szx + R[1, 0] * sxy + R[1, 1] * syy + R[1, 2] * szy
            + R[2, 0] * sxz + R[2, 1] * syz + R[2, 2] * szz)


# Scratch layout of a block of cells for :func:`rotations_block`: one row per quantity, one column per cell (structure
# of arrays), so that the arithmetic runs across cells in SIMD lanes.
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


@nb.njit(cache=True, nogil=True)
def fit_rotations_scalar(S: np.ndarray, R: np.ndarray) -> None:  # pragma: no cover - compiled
    """Cell-by-cell :func:`rotation_from_covariance` of a (k, 3, 3) stack into ``R`` (the reference of the blocks)."""
    for i in range(S.shape[0]):
        best_rotation(S[i], R[i])


def fit_rotations(S: np.ndarray) -> np.ndarray:
    """Best-fit rotations of a stack of 3×3 matrices.

    Parameters
    ----------
    S : (k, 3, 3) float array
        Cell covariance matrices ``Σ_j w_j e_j e'_jᵀ``.

    Returns
    -------
    (k, 3, 3) float64 array
        ``R[i]`` maximises ``tr(R[i] S[i])`` over rotations (det = +1).
    """
    S = np.ascontiguousarray(S, dtype=np.float64)
    if S.ndim != 3 or S.shape[1:] != (3, 3):
        raise ValueError(f"expected a (k, 3, 3) stack of matrices, got shape {S.shape}")
    R = np.empty_like(S)
    # About 20 operations per matrix entry: weigh a matrix like two edge terms of a cell.
    policy.run("fit_rotations", 2 * len(S), lambda: _fit_serial(S, R), lambda: _fit_parallel(S, R))
    return R


def fit_rotations_svd(S: np.ndarray) -> np.ndarray:
    """Reference implementation with ``numpy.linalg.svd`` (slower; used to check :func:`fit_rotations`).

    ``S = U Σ Vᵀ``, ``R = V Uᵀ``; where ``det R < 0`` the column of ``U`` of the smallest singular value is negated.

    Parameters
    ----------
    S : (k, 3, 3) float array

    Returns
    -------
    (k, 3, 3) float64 array
    """
    S = np.asarray(S, dtype=np.float64)
    U, _, Vt = np.linalg.svd(S)
    R = np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2)
    flip = np.linalg.det(R) < 0
    if np.any(flip):
        U = U.copy()
        U[flip, :, 2] *= -1.0
        R[flip] = np.swapaxes(Vt[flip], 1, 2) @ np.swapaxes(U[flip], 1, 2)
    return R
