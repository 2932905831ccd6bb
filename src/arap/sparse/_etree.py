"""Elimination trees of symmetric sparse patterns: CHOLMOD's postorder of a fill-reducing ordering, and the
factor's column counts, without forming the factor (compiled kernels)."""

from __future__ import annotations

import numba as nb
import numpy as np

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernels below are defined)
from arap.sparse._csr_permute import permuted_rows


@nb.njit(cache=True, nogil=True)
def postorder(indptr, indices, perm):  # pragma: no cover - compiled
    # Elimination tree of the permuted pattern (Liu's algorithm with path compression), its column counts (Gilbert,
    # Ng and Peyton's skeleton-matrix method) and a depth-first postorder that visits the children of every node in
    # increasing order of their counts (ties by index), so that the heaviest child ends next to its parent.
    inv, ptr = permuted_rows(indptr, perm)
    n = perm.shape[0]
    adj = np.empty(ptr[n], np.int64)
    for i in range(n):
        p = ptr[i]
        for q in range(indptr[perm[i]], indptr[perm[i] + 1]):
            adj[p] = inv[indices[q]]
            p += 1
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    for k in range(n):
        for p in range(ptr[k], ptr[k + 1]):
            i = adj[p]
            while i != -1 and i < k:
                nxt = ancestor[i]
                ancestor[i] = k
                if nxt == -1:
                    parent[i] = k
                i = nxt
    post = depth_first(parent, np.zeros(n, np.int64))
    count = column_counts(ptr, adj, parent, post)
    post = depth_first(parent, count)
    out = np.empty(n, np.int64)
    for i in range(n):
        out[i] = perm[post[i]]
    return out


@nb.njit(cache=True, nogil=True)
def depth_first(parent, weight):  # pragma: no cover - compiled
    # Children lists in increasing (weight, index), by a bucket pass over the weights, then an iterative DFS.
    n = parent.shape[0]
    bucket_head = np.full(n, -1, np.int64)
    bucket_next = np.full(n, -1, np.int64)
    for j in range(n):
        if parent[j] != -1:
            w = min(max(weight[j], 0), n - 1)
            bucket_next[j] = bucket_head[w]
            bucket_head[w] = j
    head = np.full(n, -1, np.int64)
    nxt = np.full(n, -1, np.int64)
    for w in range(n - 1, -1, -1):
        j = bucket_head[w]
        while j != -1:
            after = bucket_next[j]
            p = parent[j]
            nxt[j] = head[p]
            head[p] = j
            j = after
    post = np.empty(n, np.int64)
    stack = np.empty(n, np.int64)
    k = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            p = stack[top]
            c = head[p]
            if c == -1:
                top -= 1
                post[k] = p
                k += 1
            else:
                head[p] = nxt[c]
                top += 1
                stack[top] = c
    return post


@nb.njit(cache=True, nogil=True)
def column_counts(ptr, adj, parent, post):  # pragma: no cover - compiled
    # Nonzeros of every column of the Cholesky factor, diagonal included, without forming it: each row subtree's
    # leaves add one, the least common ancestor of consecutive leaves (found with a path-compressed forest) takes
    # one off, and the differences are summed up the tree.
    n = parent.shape[0]
    first = np.full(n, -1, np.int64)
    delta = np.zeros(n, np.int64)
    for k in range(n):
        j = post[k]
        if first[j] == -1:
            delta[j] = 1  # a leaf of the tree
        while j != -1 and first[j] == -1:
            first[j] = k
            j = parent[j]
    ancestor = np.arange(n)
    max_first = np.full(n, -1, np.int64)
    prev_leaf = np.full(n, -1, np.int64)
    for k in range(n):
        j = post[k]
        if parent[j] != -1:
            delta[parent[j]] -= 1
        for p in range(ptr[j], ptr[j + 1]):
            i = adj[p]
            if i <= j or first[j] <= max_first[i]:
                continue  # not a leaf of row i's subtree
            max_first[i] = first[j]
            previous = prev_leaf[i]
            prev_leaf[i] = j
            delta[j] += 1
            if previous != -1:
                q = previous
                while q != ancestor[q]:
                    q = ancestor[q]
                s = previous
                while s != q:
                    up = ancestor[s]
                    ancestor[s] = q
                    s = up
                delta[q] -= 1
        if parent[j] != -1:
            ancestor[j] = parent[j]
    for j in range(n):
        if parent[j] != -1:
            delta[parent[j]] += delta[j]
    return delta
