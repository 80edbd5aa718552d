"""The eigenpairs found so far: de-duplication, clusters of close eigenvalues, Rayleigh-Ritz.

A shift-invert run may return a pair that an earlier run found already (a
neighbouring shift), or one member of a degenerate pair (cos m theta / sin m
theta) in one run and the other in the next.  :meth:`KnownPairs.add` keeps
every independent direction once: pairs whose eigenvalues agree to
``CLUSTER_RELATIVE`` are Rayleigh-Ritz'ed together on the span of their vectors,
which keeps both members of a degenerate pair and drops only directions that
are numerically the same.  The known pairs are the deflation set of
:mod:`copdea_fem.fe.eigen.krylov`.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg


class KnownPairs:
    """Eigenpairs of ``A x = lam B x`` found so far, de-duplicated.

    Parameters
    ----------
    A, B : scipy.sparse matrix, shape (n, n)
    hermitian : bool
        Vectors are B-normalised and Ritz'ed with ``eigh`` if True.
    real_arithmetic : bool
        Real symmetric pencil: vectors are kept real.
    scale : float
        Size of the band's lam-plane image (rad^2/s^2): the absolute floor of
        the cluster tolerance, so that ``lam ~ 0`` still clusters.

    Attributes
    ----------
    values : numpy.ndarray of complex, shape (k,)
        ``lam`` (rad^2/s^2).
    vectors : numpy.ndarray, shape (n, k)
        Unit vectors (B-norm if Hermitian, else 2-norm).
    """

    # Duplicate directions: normalised vectors whose Gram matrix has an
    # eigenvalue below 1e-6 of its largest are treated as one (an angle below
    # ~1e-3 rad).  Eigenvector errors at converged tolerances are ~residual/gap
    # (<< 1e-3) while distinct eigenvectors of a Hermitian pencil are
    # B-orthogonal (angle pi/2).
    DUPLICATE_GRAM_RATIO = 1e-6
    # Eigenvalues closer than 1e-6 (relative) are grouped and Rayleigh-Ritz'ed
    # together; grouping too much is harmless (Ritz separates them), grouping
    # too little could keep a duplicate.
    CLUSTER_RELATIVE = 1e-6

    def __init__(self, A, B, hermitian: bool, real_arithmetic: bool, scale: float):
        self.A, self.B = A, B
        self.n = A.shape[0]
        self.hermitian = hermitian
        self.real_arithmetic = real_arithmetic
        self.scale = scale
        self.dtype = np.dtype(float) if real_arithmetic else np.dtype(complex)
        self.clear()

    def clear(self) -> None:
        """Forget every pair."""
        self.values = np.zeros(0, complex)
        self.vectors = np.zeros((self.n, 0), dtype=self.dtype)

    @property
    def count(self) -> int:
        return int(self.values.shape[0])

    def add(self, values, vectors) -> None:
        """Append pairs, then Rayleigh-Ritz every cluster of close eigenvalues.

        Inside a cluster the stacked vectors are reduced to an orthonormal
        (B-orthonormal if Hermitian) basis of their span, dropping directions
        that are duplicates (Gram eigenvalue below ``DUPLICATE_GRAM_RATIO``), and
        the pencil is solved on that basis.  Degenerate partners (cos m theta /
        sin m theta) are independent directions and are both kept; a pair found
        twice spans one direction and is kept once.
        """
        values = np.asarray(values, dtype=complex)
        vectors = np.asarray(vectors)
        if vectors.ndim == 1:
            vectors = vectors[:, None]
        if self.real_arithmetic and np.iscomplexobj(vectors):
            vectors = vectors.real
        all_values = np.concatenate([self.values, values])
        vectors = vectors.astype(self.dtype, copy=False)
        all_vectors = np.concatenate([self.vectors, vectors], axis=1)
        new_values, new_vectors = [], []
        for members in self.clusters(all_values):
            if len(members) == 1:
                index = members[0]
                vector = all_vectors[:, index]
                norm = self.norm(vector[:, None])[0]
                new_values.append(all_values[index:index + 1])
                new_vectors.append((vector / norm)[:, None])
                continue
            ritz_values, ritz_vectors = self.ritz(all_vectors[:, members])
            new_values.append(ritz_values)
            new_vectors.append(ritz_vectors)
        self.values = np.concatenate(new_values) if new_values else np.zeros(0, complex)
        self.vectors = (np.concatenate(new_vectors, axis=1) if new_vectors
                        else np.zeros((self.n, 0), self.dtype))

    def contains(self, values, vectors) -> np.ndarray:
        """Which of the pairs ``(values, vectors)`` are known already: boolean mask.

        A pair is known when its eigenvalue lies within ``CLUSTER_RELATIVE`` of known
        ones and its vector lies in their span (the part outside is below
        ``sqrt(DUPLICATE_GRAM_RATIO)`` = 1e-3 of its norm, the angle under which
        :meth:`add` treats two directions as one).  A degenerate partner of a known
        pair has the same eigenvalue but a direction outside the span: unknown.
        """
        values = np.asarray(values, dtype=complex)
        known = np.zeros(values.size, dtype=bool)
        floor = 1e-6 * self.scale
        for index, value in enumerate(values):
            tolerance = self.CLUSTER_RELATIVE * (np.abs(self.values) + abs(value) + floor)
            members = np.flatnonzero(np.abs(self.values - value) <= tolerance)
            if not members.size:
                continue
            vector = vectors[:, index]
            span = self.vectors[:, members]
            weighted = self.B @ span if self.hermitian else span
            gram = span.conj().T @ weighted
            coefficients = np.linalg.lstsq(gram, weighted.conj().T @ vector, rcond=None)[0]
            outside = vector - span @ coefficients
            ratio = self.norm(outside[:, None])[0] / max(self.norm(vector[:, None])[0], 1e-300)
            known[index] = ratio <= np.sqrt(self.DUPLICATE_GRAM_RATIO)
        return known

    def clusters(self, values: np.ndarray) -> list[list[int]]:
        """Groups of indices whose eigenvalues are within ``CLUSTER_RELATIVE`` (transitively)."""
        count = values.size
        parent = list(range(count))

        def root(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        floor = 1e-6 * self.scale  # absolute floor so that lam ~ 0 still clusters
        order = np.argsort(values.real, kind="stable")
        for position, i in enumerate(order):
            for j in order[position + 1:]:
                tolerance = self.CLUSTER_RELATIVE * (max(abs(values[i]), abs(values[j])) + floor)
                if values[j].real - values[i].real > tolerance:
                    break
                if abs(values[j] - values[i]) <= tolerance:
                    parent[root(j)] = root(i)
        groups: dict[int, list[int]] = {}
        for i in range(count):
            groups.setdefault(root(i), []).append(i)
        return [sorted(members) for _, members in sorted(groups.items())]

    def norm(self, vectors: np.ndarray) -> np.ndarray:
        """B-norm (Hermitian) or 2-norm of each column."""
        if self.hermitian:
            return np.sqrt(np.abs(np.einsum("ij,ij->j", vectors.conj(), self.B @ vectors)))
        return np.linalg.norm(vectors, axis=0)

    def ritz(self, vectors: np.ndarray):
        """Rayleigh-Ritz of the pencil on span(vectors), duplicates removed."""
        weighted = self.B @ vectors if self.hermitian else vectors
        gram = vectors.conj().T @ weighted
        gram = 0.5 * (gram + gram.conj().T)
        gram_values, gram_vectors = np.linalg.eigh(gram)
        keep = gram_values > self.DUPLICATE_GRAM_RATIO * gram_values[-1]
        basis = vectors @ (gram_vectors[:, keep] / np.sqrt(gram_values[keep]))
        projected_a = basis.conj().T @ (self.A @ basis)
        projected_b = basis.conj().T @ (self.B @ basis)
        if self.hermitian:
            projected_a = 0.5 * (projected_a + projected_a.conj().T)
            projected_b = 0.5 * (projected_b + projected_b.conj().T)
            ritz_values, coefficients = scipy.linalg.eigh(projected_a, projected_b)
            ritz_values = ritz_values.astype(complex)
        else:
            ritz_values, coefficients = scipy.linalg.eig(projected_a, projected_b)
        ritz_vectors = basis @ coefficients
        ritz_vectors = ritz_vectors / self.norm(ritz_vectors)[None, :]
        if self.real_arithmetic:
            ritz_vectors = ritz_vectors.real
        return ritz_values, ritz_vectors
