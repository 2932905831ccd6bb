"""Horn's quaternion method for the best-fit rotation of one 3×3 covariance matrix.

For a cell covariance ``S = Σ_j w_j e_j e'_jᵀ`` (rest edge ``e``, deformed edge ``e'``) the local step of ARAP
(Sorkine & Alexa 2007) needs the rotation ``R`` maximising ``tr(R S)``. The textbook answer is ``R = V Uᵀ`` from the
SVD ``S = U Σ Vᵀ``, with the column of ``U`` of the smallest singular value negated when ``det(V Uᵀ) < 0``.

Horn's method (Horn 1987) gives the same rotation: it is the unit quaternion that is the dominant eigenvector of a
symmetric, traceless 4×4 matrix ``N(S)``; its largest eigenvalue is found by Newton's method on the characteristic
quartic started above the root (as in Theobald's QCP, 2005), and the eigenvector is read off the adjugate of
``N − λI``. The reflection case needs no special branch: the quaternion is always a proper rotation, and it is the
one the SVD recipe gives. When the dominant eigenvalue is (nearly) repeated, the optimum is not unique and a cyclic
Jacobi eigen-solver picks one.

These are the one-matrix (scalar) kernels; :mod:`arap.method.rotations` runs the same method on blocks of cells in SIMD
lanes and falls back to :func:`rotation_from_covariance` for the cells that need the careful path.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


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
