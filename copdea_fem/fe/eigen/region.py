"""The band as a region of the lam-plane, sampled in cells, and the cover test of discs.

``lam = omega**2`` (rad^2/s^2).  A shift ``sigma`` whose run has found every
eigenvalue with ``|lam - sigma| < r`` covers the open disc of radius ``r``;
the band is done when discs cover :class:`BandRegion`.  The fraction of the
region's cells inside certified discs is the progress of a band solve
(:meth:`BandRegion.covered_fraction`).
"""

from __future__ import annotations

import math
import threading

import numpy as np

from copdea_fem.fe.eigen.frequencies import TWO_PI, format_hz, format_radius

#: :meth:`BandRegion.first_shift` of the last regions asked (cells -> shift)
_FIRST_SHIFTS: dict = {}
_FIRST_SHIFTS_LOCK = threading.Lock()


class BandRegion:
    """The band as a compact region of the lam-plane, with a sampled cover test.

    In the frequency plane the band is the rectangle ``[f_lo, f_hi] x
    [-h, h]`` (``Re f`` x ``Im f``, Hz), enlarged by ``margin_hz``.  Its image
    under ``lam = (2 pi f)^2`` is what the shifts' discs must cover.  For a
    Hermitian pencil only the real axis matters: the segment
    ``[(2 pi f_lo)^2, (2 pi f_hi)^2]``, extended down to ``-(2 pi h)^2`` when
    ``f_min = 0`` (unstable modes, ``Re f = 0``).

    The region is sampled by cells; each cell is stored as the lam of its
    centre and a radius ``slack`` that bounds the distance from the centre to
    any lam of the cell (``|dlam/df| = 2 (2 pi)^2 |f|``), so "centre + slack
    inside an open disc" proves the whole cell is inside.
    """

    SEGMENT_CELLS = 4000  # 1-D: cell width (lam_hi - lam_lo) / 4000
    GRID_CELLS_RE = 240   # 2-D: cells along Re f
    GRID_CELLS_IM = 60    # 2-D: cells along Im f (both signs)

    def __init__(self, f_min, f_max, imag_max_hz, margin_hz, hermitian):
        self.hermitian = hermitian
        f_lo = max(f_min - margin_hz, 0.0)
        f_hi = f_max + margin_hz
        h = imag_max_hz + margin_hz
        if hermitian:
            lam_lo = (TWO_PI * f_lo) ** 2 if f_min > 0 else -((TWO_PI * h) ** 2)
            lam_hi = (TWO_PI * f_hi) ** 2
            edges = np.linspace(lam_lo, lam_hi, self.SEGMENT_CELLS + 1)
            self.centres = 0.5 * (edges[1:] + edges[:-1]) + 0j
            self.slack = np.full(self.centres.shape, 0.5 * (edges[1] - edges[0]))
        else:
            re_edges = np.linspace(f_lo, f_hi, self.GRID_CELLS_RE + 1)
            im_count = self.GRID_CELLS_IM if h > 0 else 1
            im_edges = np.linspace(-h, h, im_count + 1) if h > 0 else np.array([0.0, 0.0])
            re_c = 0.5 * (re_edges[1:] + re_edges[:-1])
            im_c = 0.5 * (im_edges[1:] + im_edges[:-1])
            f_centre = (re_c[:, None] + 1j * im_c[None, :]).ravel()
            half_diagonal = 0.5 * math.hypot(re_edges[1] - re_edges[0], im_edges[1] - im_edges[0])
            self.centres = (TWO_PI * f_centre) ** 2
            # |lam(f) - lam(fc)| = (2 pi)^2 |f - fc| |f + fc| <= (2 pi)^2 d (2|fc| + d)
            self.slack = TWO_PI**2 * half_diagonal * (2.0 * np.abs(f_centre) + half_diagonal)
        self.real_extent = (float(self.centres.real.min() - self.slack.max()),
                            float(self.centres.real.max() + self.slack.max()))
        self.scale = max(abs(self.real_extent[0]), abs(self.real_extent[1]),
                         float(np.max(np.abs(self.centres))))

    @staticmethod
    def format_hz(point) -> str:
        """A point of the region's plane (here lam) as a frequency text (progress lines)."""
        return format_hz(point)

    @staticmethod
    def format_radius(sigma, radius) -> str:
        """A disc about the real shift ``sigma`` as text (progress lines)."""
        return format_radius(sigma, radius)

    def uncovered(self, shifts: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """Shortfall of every cell: ``min_j (|c - sigma_j| + slack - r_j)``; > 0 = not covered."""
        if shifts.size == 0:
            return np.full(self.centres.shape, np.inf)
        distance = np.abs(self.centres[:, None] - shifts[None, :]) + self.slack[:, None]
        with np.errstate(invalid="ignore"):
            shortfall = distance - radii[None, :]
        shortfall[:, np.isinf(radii)] = -np.inf
        return shortfall.min(axis=1)

    def covered_fraction(self, shifts: np.ndarray, radii: np.ndarray) -> float:
        """Share of the region's cells inside the discs (cells are equal in ``f`` on a
        general pencil's rectangle, in ``lam`` on a Hermitian segment)."""
        return float(np.mean(self.uncovered(shifts, radii) <= 0))

    def first_shift(self) -> float:
        """Real shift nearest the farthest point of the region (Chebyshev centre on the axis).

        The ternary search is not free; the orders of the axisymmetric engine ask it of
        two regions 33 times in one solve, so the answer is kept per region
        (:data:`_FIRST_SHIFTS`, keyed by the cells it reads: the same number)."""
        key = (self.centres.tobytes(), self.slack.tobytes(), self.real_extent, self.scale)
        shift = _FIRST_SHIFTS.get(key)
        if shift is None:
            shift = self._first_shift()
            with _FIRST_SHIFTS_LOCK:          # sectors may run in threads
                if len(_FIRST_SHIFTS) >= 16:
                    _FIRST_SHIFTS.clear()
                _FIRST_SHIFTS[key] = shift
        return shift

    def _first_shift(self) -> float:
        lo, hi = self.real_extent

        def farthest(sigma):
            return float(np.max(np.abs(self.centres - sigma) + self.slack))

        for _ in range(100):  # ternary search on a convex function; 100 steps shrink by 1e-17
            third = (hi - lo) / 3.0
            if third <= 1e-12 * self.scale:
                break
            if farthest(lo + third) <= farthest(hi - third):
                hi = hi - third
            else:
                lo = lo + third
        return 0.5 * (lo + hi)
