"""Mode tracking along a parameter sweep: MAC, degenerate pairs, assignment.

Pure functions on arrays: no FE objects, no files.  A sweep point's modes
arrive as a :class:`ModeSet` (frequencies, labels, and shapes in a form that
can be compared with the neighbouring point); :func:`track_modes` follows
every mode along a sequence of points and gives each one a stable track id.

How a mode is followed from point ``p`` to the next point ``q``
----------------------------------------------------------------
1. *Units.*  At each point, degenerate pairs (``cos m theta`` / ``sin m
   theta``: same kind, same ``m >= 1``, frequencies within
   ``pair_tolerance``) form one unit; every other mode is a unit of its own.
   An eigensolver returns an arbitrary basis of a degenerate eigenspace, so
   the single-vector MAC of a pair member is meaningless; the unit's
   *subspace* MAC is not (see :func:`subspace_mac`).  A pair that splits at
   ``q`` (two singles beyond the tolerance, e.g. a square frame) is kept
   together when both singles lie in the pair's span at ``p``
   (:func:`_inherit_pairs`), so a pair stays a pair.  Inside a pair, the two
   members continue the previous point's members by their own (single-vector)
   MAC (:func:`_continue_members`): where an imperfection splits the pair
   (an anisotropic pre-stretch, a mass), each member's track is continuous
   through the split and beyond, even where the members' frequency order
   turns over (at a degenerate point either basis continues equally well).
2. *Similarity.*  Subspace MAC between every unit at ``p`` and every unit at
   ``q``: with the mass matrix of ``q`` when both points share one FE space
   (same mesh, same order: the vectors are coefficient arrays of the same
   basis), else on a geometry-independent sampling (``ModeSet.sampled``).
3. *Assignment.*  The Hungarian algorithm
   (:func:`scipy.optimize.linear_sum_assignment`) minimises the total cost
   ``(1 - MAC) + label_weight * [base labels differ]
   + frequency_weight * |ln(f_q / f_p)|`` over one-to-one matchings.  A match
   is accepted if its MAC is at least ``mac_min``; otherwise (and for units
   left over) the unit at ``q`` opens a new track and the one at ``p`` ends.

Why this holds through crossings, veerings and pairs
----------------------------------------------------
* Crossing (modes of different symmetry, which do not interact, e.g. ``m``
  differs): the shapes do not change through the crossing, so the MAC matrix
  between neighbours is a permutation with entries ~1; the assignment follows
  the shapes and the tracks cross.
* Veering (avoided crossing of modes that interact): the two shapes rotate
  into each other inside a 2-D subspace over a parameter width ~ coupling.
  When the sweep resolves that width (several points across it) each step's
  MAC is highest along the continuous branch, so the tracks follow the
  branches and do not cross; the track keeps its id while its local label
  changes (e.g. ``(0,1)`` -> ``(0,2)``), as the physics says.  A veering much
  narrower than the step cannot be told from a crossing at that sampling:
  the MAC then follows the shape and the tracks cross -- refine the axis
  there if the branch is wanted.  The label and frequency terms only break
  near-ties (``label_weight`` 0.25 < the MAC gap of any decisive step).
* Pairs are compared as 2-D subspaces, whatever basis the solver returned.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from copdea_fem.mac import subspace_mac_from_products


class TrackingInputError(ValueError):
    """A tracking argument is outside what is allowed; the message names it."""


@dataclass(frozen=True)
class TrackingSettings:
    """Knobs of :func:`track_modes` (all dimensionless).

    Attributes
    ----------
    mac_min : float
        Smallest (subspace) MAC accepted for a match.  Unrelated modes of a
        10^3..10^4-DOF membrane at neighbouring points have MAC < 0.05, the
        same mode > 0.8 even mid-veering on a resolved step, so 0.3 separates
        them with margin on both sides.
    label_weight : float
        Cost of a change of base label ``(m,n)`` along a match: 0.25, below
        any decisive MAC difference (> 0.5) and above round-off ties.
    frequency_weight : float
        Cost per unit of ``|ln(f_q / f_p)|``: 0.5, so a 10 % jump costs 0.05
        -- a tie-breaker for near-equal MACs, not a constraint.
    pair_tolerance : float
        Relative frequency difference below which two modes of the same kind
        and ``m >= 1`` are a degenerate pair: 1 %.  A square frame or an
        unstructured mesh splits pairs by < 0.1 % here; distinct modes of one
        ``m`` (next radial order, in-plane branches) are > 10 % apart.
    """

    mac_min: float = 0.3
    label_weight: float = 0.25
    frequency_weight: float = 0.5
    pair_tolerance: float = 0.01

    def __post_init__(self):
        for name, low, high in (("mac_min", 0.0, 1.0), ("label_weight", 0.0, 10.0),
                                ("frequency_weight", 0.0, 10.0), ("pair_tolerance", 0.0, 0.5)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                    not low <= value <= high:
                raise TrackingInputError(f"tracking.{name} = {value!r} is not allowed; "
                                         f"allowed: a number in [{low:g}, {high:g}]")


@dataclass
class ModeSet:
    """The modes of one sweep point, as the tracker compares them.

    Attributes
    ----------
    freq_hz : numpy.ndarray, shape (k,)
        Natural frequencies Re f [Hz].
    labels : list of str
        Local labels: ``(m,n)``, ``(m,n)a``, ``ip(m,n)b``, ``P1``, ``IP2`` ...
    kinds : list of str
        ``out-of-plane``, ``in-plane``, ``pumping`` ...
    m : numpy.ndarray of int, shape (k,)
        Circumferential wavenumber (0 where unknown / axisymmetric).
    vectors : numpy.ndarray, shape (n, k), optional
        Shape vectors (e.g. full membrane-space coefficient arrays) [any unit].
    weighted : numpy.ndarray, shape (n, k), optional
        ``W @ vectors`` with the inner-product matrix ``W`` of this point (the
        mass matrix); ``None`` = plain inner product (``W = I``).
    space : hashable, optional
        Two sets with equal, non-None ``space`` have comparable ``vectors``
        (same basis functions, e.g. same mesh and order).
    sampled : numpy.ndarray, shape (k, s), optional
        A geometry-independent sampling of each shape with the quadrature
        weights folded in (``sqrt(w_i) * u(x_i)``), compared by the plain
        inner product when the spaces differ.
    """

    freq_hz: np.ndarray
    labels: list
    kinds: list
    m: np.ndarray
    vectors: np.ndarray | None = None
    weighted: np.ndarray | None = None
    space: object = None
    sampled: np.ndarray | None = None
    _gram: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        self.freq_hz = np.asarray(self.freq_hz, dtype=float).ravel()
        k = self.freq_hz.size
        self.m = np.asarray(self.m, dtype=int).ravel()
        self.labels, self.kinds = list(self.labels), list(self.kinds)
        if not (len(self.labels) == len(self.kinds) == self.m.size == k):
            raise TrackingInputError(
                f"ModeSet: freq_hz, labels, kinds and m must have one entry per mode; got "
                f"{k}, {len(self.labels)}, {len(self.kinds)}, {self.m.size}")
        for name in ("vectors", "weighted"):
            array = getattr(self, name)
            if array is not None:
                array = np.asarray(array)
                if array.ndim != 2 or array.shape[1] != k:
                    raise TrackingInputError(f"ModeSet.{name} must have shape (n, {k}); "
                                             f"got {array.shape}")
                setattr(self, name, array)
        if self.weighted is not None and (self.vectors is None or
                                          self.weighted.shape != self.vectors.shape):
            raise TrackingInputError("ModeSet.weighted needs vectors of the same shape")
        if self.sampled is not None:
            self.sampled = np.asarray(self.sampled)
            if self.sampled.ndim != 2 or self.sampled.shape[0] != k:
                raise TrackingInputError(f"ModeSet.sampled must have shape ({k}, s); got "
                                         f"{self.sampled.shape}")

    def __len__(self) -> int:
        return int(self.freq_hz.size)

    @property
    def gram(self) -> np.ndarray:
        """``V^H W V`` (k x k) with this point's own inner product."""
        if self._gram is None:
            weighted = self.vectors if self.weighted is None else self.weighted
            self._gram = self.vectors.conj().T @ weighted
        return self._gram


@dataclass
class TrackingResult:
    """Track ids along a sequence of :class:`ModeSet`.

    Attributes
    ----------
    track : list of numpy.ndarray of int
        ``track[p][i]``: track id of mode ``i`` at point ``p``.
    member : list of numpy.ndarray of int
        Position of the mode inside its unit (0 for singles; 0/1 for the
        members of a pair: at a pair's first point the lower/upper one, then
        each continues its predecessor's shape, :func:`_continue_members`).
    unit_size : list of numpy.ndarray of int
        1 for a single mode, 2 for a degenerate pair.
    mac_previous : list of numpy.ndarray
        (Subspace) MAC of the mode's unit with its predecessor on the track;
        NaN where the track starts.
    labels : dict
        Track id -> track label: the label it carries at most points (base
        label for pairs and m >= 1; an m = 0 single keeps its a/b suffix)
        (ties: the first), with ``"->"`` joining the distinct base labels in
        order when the label changes along the track (a resolved veering).
    """

    track: list
    member: list
    unit_size: list
    mac_previous: list
    labels: dict


# --------------------------------------------------------------------------- units


def base_label(label: str) -> str:
    """Label without the pair suffix: ``(1,1)a`` -> ``(1,1)``, ``ip(2,1)c`` -> ``ip(2,1)``."""
    return re.sub(r"(?<=\))[a-z]+$", "", label)


def group_degenerate(freq_hz, kinds, m, pair_tolerance: float) -> list[tuple[int, ...]]:
    """Units of one point: degenerate pairs and single modes, by lowest frequency.

    Two modes pair when they have the same kind, the same ``m >= 1`` and
    ``|f_1 - f_2| <= pair_tolerance * max(f_1, f_2)``; pairs are formed
    greedily between frequency neighbours, each mode in at most one pair.

    Returns
    -------
    list of tuple of int
        Mode indices of each unit, the pair's members in frequency order.
    """
    freq_hz = np.asarray(freq_hz, dtype=float)
    m = np.asarray(m, dtype=int)
    order = np.argsort(freq_hz, kind="stable")
    used: set[int] = set()
    units: list[tuple[int, ...]] = []
    for position, i in enumerate(order):
        if i in used:
            continue
        partner = None
        if m[i] >= 1:
            for j in order[position + 1:]:
                if freq_hz[j] - freq_hz[i] > pair_tolerance * max(abs(freq_hz[j]), 1e-300):
                    break
                if j not in used and kinds[j] == kinds[i] and m[j] == m[i]:
                    partner = int(j)
                    break
        used.add(int(i))
        if partner is None:
            units.append((int(i),))
        else:
            used.add(partner)
            units.append((int(i), partner))
    units.sort(key=lambda unit: freq_hz[list(unit)].min())
    return units


class _Similarity:
    """Subspace MAC between units of two neighbouring points (NaN: not comparable)."""

    def __init__(self, previous: ModeSet, current: ModeSet):
        self.kind = None
        if previous.space is not None and previous.space == current.space and \
                previous.vectors is not None and current.vectors is not None and \
                previous.vectors.shape[0] == current.vectors.shape[0]:
            weighted = current.vectors if current.weighted is None else current.weighted
            self.cross = previous.vectors.conj().T @ weighted   # W of the current point
            self.gram_previous, self.gram_current = previous.gram, current.gram
            self.kind = "vectors"
        elif previous.sampled is not None and current.sampled is not None and \
                previous.sampled.shape[1] == current.sampled.shape[1]:
            self.cross = previous.sampled.conj() @ current.sampled.T
            self.gram_previous = previous.sampled.conj() @ previous.sampled.T
            self.gram_current = current.sampled.conj() @ current.sampled.T
            self.kind = "sampled"

    def __call__(self, unit_previous, unit_current) -> float:
        if self.kind is None:
            return math.nan
        i, j = list(unit_previous), list(unit_current)
        return subspace_mac_from_products(self.cross[np.ix_(i, j)],
                                       self.gram_previous[np.ix_(i, i)],
                                       self.gram_current[np.ix_(j, j)])


def _inherit_pairs(previous_units, current_units, similarity, current: ModeSet,
                   mac_min: float) -> list:
    """Merge two current singles that together continue a previous pair."""
    if similarity.kind is None:
        return current_units
    singles = [unit for unit in current_units if len(unit) == 1]
    merged: set[int] = set()
    new_pairs = []
    for unit in previous_units:
        if len(unit) != 2:
            continue
        candidates = [single[0] for single in singles if single[0] not in merged
                      and similarity(unit, single) >= mac_min]
        if len(candidates) != 2:
            continue
        first, second = sorted(candidates, key=lambda i: current.freq_hz[i])
        if current.kinds[first] != current.kinds[second] or \
                current.m[first] != current.m[second]:
            continue
        if similarity(unit, (first, second)) >= mac_min:
            merged.update((first, second))
            new_pairs.append((first, second))
    if not new_pairs:
        return current_units
    units = [unit for unit in current_units if not (len(unit) == 1 and unit[0] in merged)]
    units += new_pairs
    units.sort(key=lambda unit: current.freq_hz[list(unit)].min())
    return units


def _continue_members(previous_unit, unit, similarity: _Similarity) -> tuple:
    """``unit``'s two members ordered as the previous pair's: swapped when the crossed
    single-vector MACs sum higher than the straight ones (the assignment of two members to
    two predecessors by their shapes); a single, or shapes that cannot be compared, keep
    the order they came in."""
    if len(previous_unit) != 2 or len(unit) != 2 or similarity.kind is None:
        return tuple(unit)
    (p0, p1), (c0, c1) = previous_unit, unit
    straight = similarity((p0,), (c0,)) + similarity((p1,), (c1,))
    crossed = similarity((p0,), (c1,)) + similarity((p1,), (c0,))
    return (c1, c0) if crossed > straight else tuple(unit)


def _unit_frequency(modes: ModeSet, unit) -> float:
    return float(np.mean(modes.freq_hz[list(unit)]))


def match_units(previous: ModeSet, current: ModeSet, previous_units, current_units,
                settings: TrackingSettings, similarity: _Similarity | None = None):
    """Hungarian assignment of the current units to the previous ones.

    Returns
    -------
    list of (int, int, float)
        ``(previous unit index, current unit index, MAC)`` of the accepted
        matches (MAC is NaN where the shapes could not be compared and the
        match rests on an equal base label).
    """
    similarity = similarity or _Similarity(previous, current)
    if not previous_units or not current_units:
        return []
    mac = np.array([[similarity(u, v) for v in current_units] for u in previous_units])
    labels_previous = [base_label(previous.labels[u[0]]) for u in previous_units]
    labels_current = [base_label(current.labels[v[0]]) for v in current_units]
    label_differs = np.array([[a != b for b in labels_current] for a in labels_previous], float)
    f_previous = np.array([_unit_frequency(previous, u) for u in previous_units])
    f_current = np.array([_unit_frequency(current, v) for v in current_units])
    with np.errstate(divide="ignore", invalid="ignore"):
        jump = np.abs(np.log(np.maximum(f_current[None, :], 1e-300)
                             / np.maximum(f_previous[:, None], 1e-300)))
    comparable = np.isfinite(mac)
    shape_cost = np.where(comparable, 1.0 - np.nan_to_num(mac), 1.0)
    cost = shape_cost + settings.label_weight * label_differs + \
        settings.frequency_weight * np.nan_to_num(jump, nan=10.0, posinf=10.0)
    rows, cols = linear_sum_assignment(cost)
    matches = []
    for i, j in zip(rows, cols):
        if comparable[i, j]:
            if mac[i, j] >= settings.mac_min:
                matches.append((int(i), int(j), float(mac[i, j])))
        elif not label_differs[i, j]:
            # shapes not comparable: continue only a track whose label is unchanged
            matches.append((int(i), int(j), math.nan))
    return matches


# --------------------------------------------------------------------------- tracking


def track_modes(sets: Sequence[ModeSet], settings: TrackingSettings | None = None
                ) -> TrackingResult:
    """Follow every mode along a sequence of points (the sweep's path).

    Parameters
    ----------
    sets : sequence of ModeSet
        One per point, in path order (neighbours consecutive).  An empty set
        (a failed point) is bridged: the next point is compared with the last
        non-empty one.
    settings : TrackingSettings, optional

    Returns
    -------
    TrackingResult
        Track ids are stable: numbered in order of first appearance, units at
        one point by frequency.
    """
    settings = settings or TrackingSettings()
    tracks, members, sizes, macs = [], [], [], []
    next_id = 0
    previous, previous_units, previous_ids = None, [], []
    history: dict[int, list[str]] = {}
    for modes in sets:
        k = len(modes)
        track = np.full(k, -1, dtype=int)
        member = np.zeros(k, dtype=int)
        size = np.ones(k, dtype=int)
        mac_previous = np.full(k, math.nan)
        tracks.append(track)
        members.append(member)
        sizes.append(size)
        macs.append(mac_previous)
        if k == 0:
            continue
        units = group_degenerate(modes.freq_hz, modes.kinds, modes.m, settings.pair_tolerance)
        unit_ids = [-1] * len(units)
        unit_mac = [math.nan] * len(units)
        if previous is not None:
            similarity = _Similarity(previous, modes)
            units = _inherit_pairs(previous_units, units, similarity, modes, settings.mac_min)
            unit_ids = [-1] * len(units)
            unit_mac = [math.nan] * len(units)
            for i, j, value in match_units(previous, modes, previous_units, units, settings,
                                           similarity):
                unit_ids[j] = previous_ids[i]
                unit_mac[j] = value
                units[j] = _continue_members(previous_units[i], units[j], similarity)
        for j, unit in enumerate(units):
            if unit_ids[j] < 0:
                unit_ids[j] = next_id
                next_id += 1
            for position, index in enumerate(unit):
                track[index] = unit_ids[j]
                member[index] = position
                size[index] = len(unit)
                mac_previous[index] = unit_mac[j]
            history.setdefault(unit_ids[j], []).append(_unit_label(modes, unit))
        previous, previous_units, previous_ids = modes, units, unit_ids
    return TrackingResult(track=tracks, member=members, unit_size=sizes, mac_previous=macs,
                          labels={tid: _track_label(labels) for tid, labels in history.items()})


def _unit_label(modes: ModeSet, unit) -> str:
    """A pair (or an m >= 1 mode) by its base label; an m = 0 single keeps its suffix.

    :mod:`copdea_fem.fe.modes` suffixes every repeated (m,n): for m = 0 the suffix tells apart
    distinct modes (e.g. the radial and the torsional ``ip(0,1)a``/``ip(0,1)b``).
    """
    if len(unit) == 2 or modes.m[unit[0]] >= 1:
        return base_label(modes.labels[unit[0]])
    return modes.labels[unit[0]]


def _track_label(labels: list[str]) -> str:
    """The most frequent label (ties: first); base labels joined by '->' if it changes.

    Suffix-only differences (``ip(0,1)a`` at one point, ``ip(0,1)`` where its
    sibling left the band) are not a change.
    """
    def most_frequent(items):
        counts = Counter(items)
        distinct = list(dict.fromkeys(items))
        return max(distinct, key=lambda item: (counts[item], -distinct.index(item)))

    bases = [base_label(label) for label in labels]
    distinct_bases = list(dict.fromkeys(bases))
    if len(distinct_bases) == 1:
        return most_frequent(labels)
    best = most_frequent(bases)
    if Counter(bases)[best] >= 0.8 * len(bases):   # an occasional flicker, not a branch change
        return most_frequent([label for label in labels if base_label(label) == best])
    return "->".join(distinct_bases)
