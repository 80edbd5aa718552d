r"""Measured mode shapes against the FE's: MAC matrix, pairing by shape, COMAC.

Pure functions on arrays: the FE side arrives as :class:`FEShapes` (the FE modes sampled
along the scan's channels, :mod:`copdea_fem.vibrometer.sampling`), the measured side as
frequencies, damping ratios and complex shapes
(:class:`copdea_fem.vibrometer.identified.IdentifiedMode`).

Units.  A circular membrane's ``cos m theta`` / ``sin m theta`` modes ((m,n)a and (m,n)b;
in-plane ip(m,n)a/b and ip(m,n)c/d) are one two-dimensional eigenspace, split a little by a
square frame or by imperfections; a measured member's orientation is whatever the
imperfections chose, so comparing it with one FE member means nothing.  Such a pair is one
*unit*, compared with a test shape as a subspace: the MAC of the test shape ``t`` with the
unit spanned by ``(f_a, f_b)`` is the squared cosine of the angle between ``t`` and the
plane, ``|P t|^2 / |t|^2`` (:func:`copdea_fem.mac.subspace_mac`), whatever basis the FE or
the measurement chose.  Every other mode (m = 0, pumping) is a unit of its own and its MAC
the ordinary one.  Units are found from the FE labels (what a mode is,
:mod:`copdea_fem.fe.modes`), never from frequency closeness.

Pairing.  One-to-one (a unit of two modes takes up to two test modes), by the Hungarian
algorithm (:func:`scipy.optimize.linear_sum_assignment`), maximising the total MAC over the
admissible pairs: those within the frequency window ``|ln(f_test / f_FE)| <= ln(1 + window)``
(default 50 %: a model that lacks an effect is off by 10 % and more - air loading moves the
(0,1) mode by 30-38 %, Sect. 5.2 - and must still be paired mode by mode) whose MAC reaches
``mac_min``.  A frequency term ``FREQUENCY_WEIGHT |ln(f_test/f_FE)| / ln(1 + window)``
(at most 0.05 of a MAC) only breaks near-ties.  A test mode without an admissible pair is
``unpaired``.  Two test modes paired with one unit take its members in frequency order.

Whether the channels can tell the shapes apart.  A pairing by shape means something only
where the FE's shapes differ at the measured channels: on one point with three directions
every pair of modes looks alike, and the "best" MAC is a choice among equals.  So each pair
carries the FE's own auto-MAC at the channels, ``fe_auto_mac``: the largest (unit) MAC of
the paired FE unit with any other FE unit inside the pair's frequency window, i.e. with
any rival the pairing could have chosen instead.  At or above ``mac_min`` the FE's own
shape would be admissible as the rival too (a test shape equal to the paired FE shape has
exactly that MAC with the rival), so shape does not decide that pair: the pair is
*indistinct* (:attr:`ModePair.distinct` False) and the caller warns.  On a PSV-like grid the
off-diagonal auto-MAC stays near 0.1; on a single point it is 1.

COMAC (coordinate MAC, Lieven & Ewins 1988) of channel c over the pairs p, with each pair's
FE shape the projection of the test shape on its unit and both scaled to unit norm and
aligned in phase (modal scale factor): ``COMAC_c = |sum_p t_pc conj(f_pc)|^2 /
(sum_p |t_pc|^2 sum_p |f_pc|^2)``; a channel where the model's shapes go wrong (a
misplaced point, a local defect) has a low COMAC.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from copdea_fem.mac import mac_matrix, subspace_mac

#: Default frequency window of a pair, relative (module notes).
DEFAULT_WINDOW = 0.5
#: Default smallest MAC of a pair: the test shape is closer to the FE unit than orthogonal
#: to it (squared cosine 1/2 = 45 degrees); unrelated shapes on ~100 channels have MAC < 0.1.
DEFAULT_MAC_MIN = 0.5
#: Weight of the frequency tie-break (a share of one MAC unit at the window's edge).
FREQUENCY_WEIGHT = 0.05

_LABEL = re.compile(
    r"^(?P<base>(?:ip)?\((?P<m>\d+),(?P<n>\d+)\))(?P<letter>[a-d]?)(?P<tie>-\d+)?$")


class CorrelationError(ValueError):
    """Bad input to the correlation: the message names the value and what is allowed."""


def unit_key(label: str) -> str:
    """The unit a labelled FE mode belongs to (module notes): ``(2,1)a`` and ``(2,1)b`` ->
    ``(2,1)``; ``ip(1,1)c``/``d`` -> ``ip(1,1)cd`` (``a``/``b`` -> ``ip(1,1)ab``); a member
    whose letter ties with its partner's (a pair turned half-way between the cos and sin
    axes: ``(2,1)a`` and ``(2,1)a-2``, :mod:`copdea_fem.fe.modes`) -> ``(2,1)`` too; an
    m = 0 mode (``(0,1)-2`` included), a pumping mode or an unlabelled one is a unit of its
    own (its label)."""
    match = _LABEL.match(label or "")
    if not match or int(match["m"]) == 0 or not match["letter"]:
        return label
    if match["base"].startswith("ip"):
        return match["base"] + ("ab" if match["letter"] in "ab" else "cd")
    return match["base"]


@dataclass(frozen=True)
class FEShapes:
    """FE modes along a scan's channels
    (:func:`copdea_fem.vibrometer.sampling.mode_shapes_at_scan`).

    Attributes
    ----------
    labels : tuple of str
        FE labels (``(m,n)a``, ``P1``, ``ip(m,n)c``...).
    freq_hz : (K,) array
        Frequencies [Hz] (real part).
    shapes : (C, K) complex array
        Velocity of each mode along each channel [any common unit].
    kinds : tuple of str
        ``out-of-plane``, ``in-plane``, ``pumping`` (:mod:`copdea_fem.fe.modes`); may be empty.
    """

    labels: tuple
    freq_hz: np.ndarray
    shapes: np.ndarray
    kinds: tuple = ()

    def __post_init__(self):
        freq = np.asarray(self.freq_hz, dtype=float).ravel()
        shapes = np.asarray(self.shapes)
        if shapes.ndim != 2 or shapes.shape[1] != len(freq) or len(self.labels) != len(freq):
            raise CorrelationError(f"FE shapes of shape {shapes.shape} with {len(freq)} "
                                   f"frequencies and {len(self.labels)} labels; allowed: "
                                   "(channels, modes) with one frequency and label per mode")
        object.__setattr__(self, "freq_hz", freq)
        object.__setattr__(self, "shapes", shapes)

    @classmethod
    def from_modes(cls, modes, shapes) -> FEShapes:
        """From :class:`copdea_fem.fe.modes.Mode` objects and their sampled shapes (C, K)."""
        return cls(tuple(mode.label for mode in modes),
                   np.array([mode.freq_hz for mode in modes]), shapes,
                   tuple(mode.kind for mode in modes))

    def units(self) -> list[tuple[int, ...]]:
        """Mode indices of each unit, members in frequency order, units by lowest frequency."""
        groups: dict[str, list[int]] = {}
        for index, label in enumerate(self.labels):
            groups.setdefault(unit_key(label) or f"#{index}", []).append(index)
        units = [tuple(sorted(group, key=lambda k: self.freq_hz[k])) for group in
                 groups.values()]
        return sorted(units, key=lambda unit: self.freq_hz[unit[0]])


@dataclass(frozen=True)
class ModePair:
    """One test mode and the FE mode it is paired with (a row of pairs.csv).

    ``label`` is ``""`` (and the FE columns NaN) when the test mode is unpaired;
    ``freq_error = f_FE / f_test - 1``; ``mac``: the MAC with the FE unit (a pair's:
    the subspace MAC); ``fe_auto_mac``: the largest MAC, at the measured channels, of the
    paired FE unit with another FE unit within the frequency window, ``fe_rival`` that
    unit's label (module notes: the channels cannot tell the two apart when
    ``fe_auto_mac >= mac_min``)."""

    test_mode: int
    test_freq_hz: float
    test_damping_ratio: float
    label: str = ""
    fe_freq_hz: float = math.nan
    freq_error: float = math.nan
    mac: float = math.nan
    fe_auto_mac: float = math.nan
    fe_rival: str = ""

    @property
    def paired(self) -> bool:
        return bool(self.label)


@dataclass(frozen=True)
class Correlation:
    """The correlation of one condition's identified modes with the FE's.

    Attributes
    ----------
    condition : str
    pairs : tuple of ModePair
        One per test mode, in test-mode order.
    mac : (T, K) array
        Single-vector MAC of every test mode with every FE mode.
    unit_mac : (T, K) array
        The MAC each test mode has with the unit of each FE mode (the subspace MAC for a
        pair's members): what the pairing used.
    fe_labels : tuple of str
    fe_freq_hz : (K,) array
    test_freq_hz : (T,) array
    comac : (C,) array
        COMAC of each channel over the pairs (NaN: no pair).
    window : float
    mac_min : float
    """

    condition: str
    pairs: tuple
    mac: np.ndarray
    unit_mac: np.ndarray
    fe_labels: tuple
    fe_freq_hz: np.ndarray
    test_freq_hz: np.ndarray
    comac: np.ndarray
    window: float = DEFAULT_WINDOW
    mac_min: float = DEFAULT_MAC_MIN

    def indistinct_pairs(self) -> tuple:
        """The pairs whose FE unit has a rival within the window that looks the same at the
        measured channels (``fe_auto_mac >= mac_min``, module notes)."""
        return tuple(pair for pair in self.pairs
                     if pair.label and pair.fe_auto_mac >= self.mac_min)

    def label_of(self, test_mode: int) -> str:
        """The FE label paired with ``test_mode`` (1-based), ``""`` if unpaired."""
        for pair in self.pairs:
            if pair.test_mode == test_mode:
                return pair.label
        raise CorrelationError(f"test_mode = {test_mode} is not allowed; allowed: "
                               f"1..{len(self.pairs)}")


def _check_positive(name, value, upper=None):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value) or value <= 0 or (upper is not None and value > upper):
        bound = f"a number in (0, {upper:g}]" if upper is not None else "a finite number > 0"
        raise CorrelationError(f"{name} = {value!r} is not allowed; allowed: {bound}")


def correlate_shapes(test_freq_hz, test_shapes, fe: FEShapes, *, test_damping_ratio=None,
                     window: float = DEFAULT_WINDOW, mac_min: float = DEFAULT_MAC_MIN,
                     condition: str = "") -> Correlation:
    """Pair test modes with FE modes by shape (module notes).

    Parameters
    ----------
    test_freq_hz : (T,) array
        Identified frequencies [Hz].
    test_shapes : (C, T) complex array
        Identified shapes along the scan's channels (the FE's channel order).
    fe : FEShapes
    test_damping_ratio : (T,) array, optional
        Identified damping ratios [-] (reported, not used).
    window : float
        Relative frequency window of a pair (> 0).
    mac_min : float
        Smallest MAC of a pair, in (0, 1].
    condition : str
        The condition's name (reported).

    Returns
    -------
    Correlation
    """
    _check_positive("window", window)
    _check_positive("mac_min", mac_min, 1.0)
    test_freq = np.asarray(test_freq_hz, dtype=float).ravel()
    test = np.asarray(test_shapes)
    test = test[:, None] if test.ndim == 1 else test
    if test.ndim != 2 or test.shape[1] != len(test_freq):
        raise CorrelationError(f"test shapes of shape {test.shape} for {len(test_freq)} "
                               "frequencies; allowed: (channels, modes)")
    if test.shape[0] != fe.shapes.shape[0]:
        raise CorrelationError(f"test shapes on {test.shape[0]} channels, FE shapes on "
                               f"{fe.shapes.shape[0]}; allowed: the same channels")
    if not np.all(np.isfinite(test)) or not np.all(np.isfinite(test_freq)):
        raise CorrelationError("test shapes or frequencies hold NaN or inf; allowed: finite")
    damping = (np.full(len(test_freq), math.nan) if test_damping_ratio is None
               else np.asarray(test_damping_ratio, dtype=float).ravel())
    n_test, n_fe = len(test_freq), len(fe.freq_hz)
    mac = mac_matrix(test, fe.shapes) if n_fe and n_test else np.zeros((n_test, n_fe))
    units = fe.units()
    unit_mac = np.zeros((n_test, n_fe))
    slots: list[tuple[int, tuple[int, ...]]] = []      # (member index, unit) per column
    for unit in units:
        for t in range(n_test):
            value = (subspace_mac(test[:, t], fe.shapes[:, list(unit)]) if len(unit) > 1
                     else mac[t, unit[0]])
            unit_mac[t, list(unit)] = value
        slots.extend((member, unit) for member in unit)
    pairs_of = _assign(test_freq, fe.freq_hz, unit_mac, slots, window, mac_min)
    pairs_of = _members_in_frequency_order(pairs_of, test_freq, fe, mac)
    pairs = []
    for t in range(n_test):
        k = pairs_of.get(t)
        common = {"test_mode": t + 1, "test_freq_hz": float(test_freq[t]),
                  "test_damping_ratio": float(damping[t])}
        if k is None:
            pairs.append(ModePair(**common))
        else:
            auto_mac, rival = _largest_rival_mac(k, test_freq[t], fe, units, window)
            pairs.append(ModePair(**common, label=fe.labels[k], fe_freq_hz=float(fe.freq_hz[k]),
                                  freq_error=float(fe.freq_hz[k] / test_freq[t] - 1),
                                  mac=float(unit_mac[t, k]), fe_auto_mac=auto_mac,
                                  fe_rival=rival))
    comac = coordinate_mac(test, fe, pairs_of, units)
    return Correlation(condition, tuple(pairs), mac, unit_mac, tuple(fe.labels),
                       fe.freq_hz.copy(), test_freq, comac, float(window), float(mac_min))


def _largest_rival_mac(k, test_freq, fe: FEShapes, units, window) -> tuple[float, str]:
    """The largest MAC at the channels of FE mode ``k``'s unit with another unit that has a
    member within the window of ``test_freq`` [Hz], and that unit's first label (module
    notes); (0, "") without a rival."""
    own = next(unit for unit in units if k in unit)
    limit = math.log1p(window)
    best, rival = 0.0, ""
    for unit in units:
        if unit == own or not any(abs(math.log(test_freq / fe.freq_hz[j])) <= limit
                                  for j in unit):
            continue
        value = subspace_mac(fe.shapes[:, list(own)], fe.shapes[:, list(unit)])
        if value > best:
            best, rival = value, unit_key(fe.labels[unit[0]]) or fe.labels[unit[0]]
    return float(best), rival


def _assign(test_freq, fe_freq, unit_mac, slots, window, mac_min) -> dict[int, int]:
    """Test mode -> FE mode index of the best admissible one-to-one pairing."""
    if not len(test_freq) or not slots:
        return {}
    members = np.array([member for member, _ in slots])
    log_ratio = np.abs(np.log(test_freq[:, None] / fe_freq[None, members]))
    limit = math.log1p(window)
    value = unit_mac[:, members]
    admissible = (log_ratio <= limit) & (value >= mac_min)
    # maximise the MAC: cost 1 - MAC (+ the tie-break); inadmissible: worse than no pair
    forbidden = 10.0
    cost = np.where(admissible, 1.0 - value + FREQUENCY_WEIGHT * log_ratio / limit, forbidden)
    rows, columns = linear_sum_assignment(cost)
    return {int(t): int(members[c]) for t, c in zip(rows, columns) if admissible[t, c]}


def _members_in_frequency_order(pairs_of, test_freq, fe: FEShapes, mac) -> dict[int, int]:
    """Two test modes on one unit take its members in frequency order; one test mode on a
    pair unit takes the member it resembles most (single MAC)."""
    by_unit: dict[str, list[int]] = {}
    for t, k in pairs_of.items():
        by_unit.setdefault(unit_key(fe.labels[k]) or f"#{k}", []).append(t)
    out = dict(pairs_of)
    units = {unit_key(fe.labels[unit[0]]) or f"#{unit[0]}": unit for unit in fe.units()}
    for key, tests in by_unit.items():
        unit = units.get(key)
        if unit is None or len(unit) < 2:
            continue
        if len(tests) >= 2:
            for t, k in zip(sorted(tests, key=lambda t: test_freq[t]), unit):
                out[t] = k
        else:
            t = tests[0]
            out[t] = max(unit, key=lambda k: mac[t, k])
    return out


def coordinate_mac(test, fe: FEShapes, pairs_of: dict, units) -> np.ndarray:
    """COMAC of each channel over the pairs (module notes); NaN without pairs."""
    n_channels = test.shape[0]
    if not pairs_of:
        return np.full(n_channels, math.nan)
    unit_of = {k: unit for unit in units for k in unit}
    cross = np.zeros(n_channels, dtype=complex)
    test_power = np.zeros(n_channels)
    fe_power = np.zeros(n_channels)
    for t, k in pairs_of.items():
        basis = fe.shapes[:, list(unit_of[k])]
        coefficients, *_ = np.linalg.lstsq(basis, test[:, t], rcond=None)
        model = basis @ coefficients          # the unit's shape nearest the test shape
        t_vec = test[:, t] / max(np.linalg.norm(test[:, t]), 1e-300)
        f_vec = model / max(np.linalg.norm(model), 1e-300)
        scale = np.vdot(f_vec, t_vec)          # modal scale factor: aligns the phase
        f_vec = f_vec * (scale / abs(scale) if abs(scale) > 0 else 1.0)
        cross += t_vec * np.conj(f_vec)
        test_power += np.abs(t_vec) ** 2
        fe_power += np.abs(f_vec) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        comac = np.abs(cross) ** 2 / (test_power * fe_power)
    return np.where(test_power * fe_power > 0, np.clip(comac, 0.0, 1.0), math.nan)


def pair_by_frequency(test_freq_hz, fe_freq_hz, fe_labels, window: float = DEFAULT_WINDOW
                      ) -> list[str]:
    """The labels frequency alone would give (nearest in ln f, one-to-one, within the window):
    what pairing by shape is measured against."""
    test_freq = np.asarray(test_freq_hz, dtype=float)
    fe_freq = np.asarray(fe_freq_hz, dtype=float)
    if not len(test_freq) or not len(fe_freq):
        return [""] * len(test_freq)
    distance = np.abs(np.log(test_freq[:, None] / fe_freq[None, :]))
    limit = math.log1p(window)
    cost = np.where(distance <= limit, distance, 10.0)
    rows, columns = linear_sum_assignment(cost)
    labels = [""] * len(test_freq)
    for t, k in zip(rows, columns):
        if distance[t, k] <= limit:
            labels[t] = fe_labels[k]
    return labels


__all__ = ["DEFAULT_MAC_MIN", "DEFAULT_WINDOW", "Correlation", "CorrelationError", "FEShapes",
           "ModePair", "coordinate_mac", "correlate_shapes", "pair_by_frequency", "unit_key"]
