r"""``copdea-fem excite``: the drive of each input that lights the target mode(s).

Criterion
---------
With the modal model of :mod:`.modal_inputs` (eq. 1), the response of in-band structural
mode j of the band to the drive ``u`` (the complex AC voltages of the K inputs, FE
convention) at its own frequency ``omega_j = 2 pi Re f_j`` is

    r_j(u) = sum_k G_jk u_k,      G_jk = p_jk / d_j(omega_j)     [m per volt]         (1)

(a mode's displacement amplitude: the band's vectors have peak |u| = 1).  The drive
minimises the leakage into the other modes O under a unit response of the targets T,
regularised so that a drive the segments cannot tell apart stays bounded:

    min_u  ||G_O u||^2 + epsilon ||u||^2    subject to   G_T u = 1 (each target)        (2)

(O: the other modes that the inputs can separate from the targets, eq. 3 below: a mode
whose row is nearly parallel to the targets' can be held down only at the cost of the
targets' response, and trading against it would raise the separable modes instead).
The modes of (2) are the out-of-plane ones by default (what the sound and an out-of-plane
vibrometer see); with ``hold_in_plane`` (``--hold-in-plane``) the in-plane modes join them.
Left out, the in-plane modes are still *watched*: their levels under the designed drive are
reported (``selectivity.csv``, kind ``in-plane``), and one above :data:`SEPARATION_DB` is
warned of - on the prestressed cone they move the points too, and a drive that cancels
an out-of-plane mode with two rings can drive one strongly.  All levels compare modal
displacement amplitudes (the band's vectors have peak |u| = 1, all three components).

``u = Q^-1 G_T^H (G_T Q^-1 G_T^H)^-1 1``, ``Q = G_O^H G_O + epsilon I``, with
``epsilon = REGULARISATION trace(G^H G) / K``.  The drive is then scaled so that its peak
AC amplitude is ``--max-ac`` [V].  Selectivity: ``20 log10(|r_j| / |r_target|)`` [dB] at each
mode's own frequency (the first target's response the reference; ``-inf`` for a mode that
no input drives at all, its row of G zero).

What the inputs cannot separate: the rows of G of a target and of its degenerate partners
(the other member of its a/b pair: the same label but for the suffix) are compared by
their singular values; a ratio below :data:`SEPARABLE_RATIO` means no drive of these inputs
tells them apart (e.g. the a and b members of an order m with too few sectors).  And each
other mode whose row is (nearly) parallel to the targets': with ``g`` its row and ``P`` the
orthogonal projector onto the span of the target rows (in C^K), its angle ``alpha`` from
the targets is

    sin alpha = ||g - P g|| / ||g||                                                    (3)

The least drive (2-norm) that gives a unit target response is ``1 / ||t||`` (one target of
row ``t``); the least one that also holds mode ``g`` at zero is ``1 / (||t|| sin alpha)``
(the component of ``conj t`` orthogonal to ``conj g``).  At the peak AC amplitude
``--max-ac`` holding it down therefore costs the target's response a factor of order
``sin alpha``; a mode with ``sin alpha <`` :data:`PARALLEL_SINE` ``= 10^(SEPARATION_DB/20)``
(alpha below 0.1002 rad: holding it down costs more than the 20 dB a separated mode is
held at) is reported as not separated from the target (e.g. the orders m and N - m, which
N equal sectors drive with one pattern: alpha = 0 on the axisymmetric engine, and to
rounding (4e-12 rad) on the 3-D quadrant, whose mesh is symmetric under x <-> y
(:mod:`copdea_fem.fe.quadrant.mirrored`); on a mesh without that symmetry (Netgen's own
quadrant mesh) the row turned off the target's by a few 1e-2 rad, which a floor of (2)
with O = that mode alone does not see).  A mode no input drives (its
row zero) is not reported (its level is ``-inf``).

Phases: the FE's complex amplitude ``u`` goes as ``e^{-i omega t}``; a drive
``V_k(t) = V_b + A_k cos(omega t + phi_k)`` has ``A_k = |u_k|``, ``phi_k = -arg u_k``
(the phase of ``electrodes.segments``' ``drive.phase``); the common phase is set so that
the input of the largest amplitude has phase 0.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass

import numpy as np

from copdea_fem.study import StudyError

logger = logging.getLogger(__name__)

#: epsilon of (2) relative to the mean squared column norm of G.
REGULARISATION = 1e-9

#: The level [dB re the target] a separated mode is held at; a mode that costs more than
#: its magnitude of the target's response to hold down is reported (:data:`PARALLEL_SINE`).
SEPARATION_DB = -20.0

#: sin alpha of (3) below which a mode's modal-force row counts as parallel to the
#: targets' (module notes: holding it down costs the target's response more than
#: ``-SEPARATION_DB`` dB at the peak AC amplitude): 10^(SEPARATION_DB / 20) = 0.1.
PARALLEL_SINE = 10.0 ** (SEPARATION_DB / 20.0)

#: Smallest singular value ratio of a target's and its partners' rows of G that the inputs
#: can still drive apart (below it their responses move together).
SEPARABLE_RATIO = 1e-6

DRIVE_COLUMNS = ("segment", "amplitude", "phase_deg")
SELECTIVITY_COLUMNS = ("label", "freq_hz", "level_db", "kind")

#: kind of a mode in ``selectivity.csv``.
OUT_OF_PLANE, IN_PLANE = "out-of-plane", "in-plane"


@dataclass
class ExcitationDesign:
    """The designed drive and what it does.

    Attributes
    ----------
    inputs : list of str
    amplitude : (K,) array
        Peak AC amplitude per input [V].
    phase_deg : (K,) array
        phi_k [deg] (module notes).
    drive : (K,) complex array
        The FE-convention complex amplitudes [V].
    labels, freq_hz, level_db : lists
        The modes of the criterion (2), their frequencies [Hz] and levels [dB re target].
    targets : list of str
    inseparable : list of str
        One line per other mode whose modal-force row is within asin(PARALLEL_SINE) of
        the targets' (module notes, eq. 3), then one per target whose a/b partners the
        inputs cannot separate.
    kinds : list of str
        :data:`OUT_OF_PLANE` or :data:`IN_PLANE` per entry of ``labels``.
    watched : list of (label, freq_hz, level_db)
        The in-plane modes left out of (2) (``hold_in_plane`` False) and their levels under
        the drive [Hz, dB re target].
    """

    inputs: list
    amplitude: np.ndarray
    phase_deg: np.ndarray
    drive: np.ndarray
    labels: list
    freq_hz: list
    level_db: list
    targets: list
    inseparable: list
    kinds: list
    watched: list

    def worst_other_db(self) -> float:
        """The highest level of a non-target mode of the criterion [dB] (-inf where there
        is none)."""
        others = [level for label, level in zip(self.labels, self.level_db)
                  if label not in self.targets]
        return max(others) if others else -np.inf

    def loud_watched(self) -> list[str]:
        """One line per watched in-plane mode above :data:`SEPARATION_DB`."""
        return [f"{label}: in-plane, at {level:+.1f} dB re the target under this drive "
                f"({freq:.1f} Hz; the criterion holds down the out-of-plane modes only: "
                "--hold-in-plane holds it down too)"
                for label, freq, level in self.watched if level > SEPARATION_DB]

    def rows(self) -> tuple[list, list, list, list]:
        """``selectivity.csv``'s columns: the criterion's modes, then the watched ones."""
        return (self.labels + [label for label, _, _ in self.watched],
                self.freq_hz + [freq for _, freq, _ in self.watched],
                self.level_db + [level for _, _, level in self.watched],
                self.kinds + [IN_PLANE] * len(self.watched))


def partner_stem(label: str) -> str:
    """A label without its a/b pair suffix: ``(2,1)a`` -> ``(2,1)``."""
    return re.sub(r"[a-d]$", "", label)


def resolve_targets(requested, labels) -> list[str]:
    """The band's labels of the requested targets: a label as written, or a pair's stem
    (``(2,1)``) for its first member (``(2,1)a``); StudyError listing the band's labels for
    an unknown one."""
    resolved = []
    for target in requested:
        if target in labels:
            resolved.append(target)
            continue
        members = [label for label in labels if partner_stem(label) == target]
        if not members:
            raise StudyError(f"--target {target!r} is not a mode of the band; allowed: "
                             + ", ".join(labels))
        resolved.append(sorted(members)[0])
    return resolved


def modal_gains(model, modes) -> np.ndarray:
    """G of (1) [m/V]: one row per ``(channel, column, label, Re f)`` of ``modes``."""
    rows = []
    for c, j, _, freq in modes:
        channel = model.channels[c]
        denominator = channel.denominators([2 * np.pi * freq])[0, j]
        rows.append(channel.participation[j] / denominator)
    return np.array(rows).reshape(len(modes), len(model.inputs))


def design_drive(model, targets, max_ac: float, f_max: float,
                 hold_in_plane: bool = False) -> ExcitationDesign:
    """The drive (2) of a :class:`.modal_inputs.ModalInputs` for the target labels, its
    peak amplitude ``max_ac`` [V], over the out-of-plane structural modes with
    ``Re f <= f_max`` [Hz] (all structural modes with ``hold_in_plane``; else the
    in-plane ones are watched: module notes)."""
    every = model.structural_modes(f_max)
    out_of_plane = {(c, j) for c, j, _, _ in model.structural_modes(f_max, out_of_plane=True)}
    modes = [mode for mode in every if hold_in_plane or mode[:2] in out_of_plane]
    left_out = [mode for mode in every if mode not in modes]
    labels = [label for _, _, label, _ in modes]
    kinds = [OUT_OF_PLANE if mode[:2] in out_of_plane else IN_PLANE for mode in modes]
    targets = resolve_targets(targets, labels)
    gain = modal_gains(model, modes)                            # (modes, K)
    target_rows = [labels.index(label) for label in targets]
    other_rows = [row for row in range(len(labels)) if row not in target_rows]
    g_target = gain[target_rows]
    # O of (2): the modes the inputs can separate from the targets (eq. 3); a parallel one
    # is reported, not traded against (holding it down costs the targets more than 20 dB)
    sines = {row: sine_from_targets(gain[row], g_target) for row in other_rows}
    parallel = [row for row in other_rows if sines[row] < PARALLEL_SINE]
    g_other = gain[[row for row in other_rows if row not in parallel]].reshape(-1, gain.shape[1])
    for label, row in zip(targets, g_target):
        if not np.any(np.abs(row) > 0):
            raise StudyError(f"--target {label}: the inputs ({', '.join(model.inputs)}) do "
                             "not drive this mode (its modal force is zero for every input); "
                             "allowed: a mode an input drives, or segments that drive its "
                             "order")
    count = gain.shape[1]
    epsilon = REGULARISATION * float(np.real(np.trace(gain.conj().T @ gain))) / count
    q = g_other.conj().T @ g_other + epsilon * np.eye(count)
    q_inverse_gt = np.linalg.solve(q, g_target.conj().T)       # (K, T)
    multipliers = np.linalg.solve(g_target @ q_inverse_gt, np.ones(len(targets)))
    drive = q_inverse_gt @ multipliers
    largest = int(np.argmax(np.abs(drive)))
    drive = drive * (max_ac / np.abs(drive[largest])) * np.exp(-1j * np.angle(drive[largest]))
    response = gain @ drive
    reference = abs(response[target_rows[0]])
    # -inf: a mode no input drives (its row of G is zero: e.g. an order m >= 1 under rings)
    levels = [float(20 * np.log10(abs(r) / reference)) if abs(r) > 0 else -np.inf
              for r in response]
    inseparable = []
    for row in parallel:
        inseparable.append(
            f"{labels[row]}: its modal-force row is {np.arcsin(sines[row]):.3g} rad from the "
            f"targets' (below {np.arcsin(PARALLEL_SINE):.4g} rad): holding it down would cost "
            f"the target's response {-20 * np.log10(max(sines[row], 1e-300)):.1f} dB at the "
            f"same peak drive (e.g. the orders m and N - m of N equal sectors), so the drive "
            f"does not try; it is at {levels[row]:.1f} dB")
    for label in targets:
        partners = [row for row, other in enumerate(labels)
                    if partner_stem(other) == partner_stem(label)]
        if len(partners) > 1:
            singular = np.linalg.svd(gain[partners], compute_uv=False)
            ratio = singular[-1] / singular[0] if singular[0] > 0 else 0.0
            if ratio < SEPARABLE_RATIO:
                inseparable.append(
                    f"{label}: its pair {', '.join(labels[row] for row in partners)} cannot be "
                    f"separated with these inputs (modal-force rows of rank "
                    f"{int(np.sum(singular > SEPARABLE_RATIO * singular[0]))} of "
                    f"{len(partners)}, singular value ratio {ratio:.1e})")
    watched = []
    for (*_, label, freq), r in zip(left_out, modal_gains(model, left_out) @ drive):
        watched.append((label, freq, float(20 * np.log10(abs(r) / reference))
                        if abs(r) > 0 else -np.inf))
    phase = np.degrees(-np.angle(drive))
    return ExcitationDesign(list(model.inputs), np.abs(drive), phase, drive, labels,
                            [freq for *_, freq in modes], levels, targets, inseparable,
                            kinds, watched)


def sine_from_targets(row, g_target) -> float:
    """sin alpha of (3) [-]: how far a mode's row of G is from the span of the target rows
    (0: parallel, 1: orthogonal); ``inf`` for a zero row (a mode no input drives)."""
    row = np.asarray(row, complex)
    norm = np.linalg.norm(row)
    if norm == 0:
        return np.inf
    basis, _ = np.linalg.qr(np.asarray(g_target, complex).T)          # (K, T)
    residual = row - basis @ (basis.conj().T @ row)
    return float(np.linalg.norm(residual) / norm)


def set_lines(design: ExcitationDesign, study) -> list[str]:
    """The ``--set`` line that feeds the drive to ``copdea-fem response``: the study's
    ``electrodes.segments`` (the whole electrode where it has none) with each segment's
    ``drive.amplitude`` [per volt of the chirp's ``excitation.amplitude``] and
    ``drive.phase`` [deg] of the design."""
    chirp = float(study.excitation.amplitude)
    segments = {segment.name: segment for segment in study.electrodes.segments}
    items = []
    for name, amplitude, phase in zip(design.inputs, design.amplitude, design.phase_deg):
        segment = segments.get(name)
        theta = [0, 360] if segment is None else [float(v) for v in segment.theta]
        where = f"theta: [{theta[0]:g}, {theta[1]:g}]"
        if segment is not None and segment.r is not None:
            where += f", r: [{float(segment.r[0]):.9g}, {float(segment.r[1]):.9g}]"
        items.append(f"{{name: {name}, {where}, drive: {{amplitude: {amplitude / chirp:.9g}, "
                     f"phase: {phase:.6g}}}}}")
    return [f"--set 'electrodes.segments=[{', '.join(items)}]'"]


__all__ = [
    "DRIVE_COLUMNS",
    "IN_PLANE",
    "OUT_OF_PLANE",
    "PARALLEL_SINE",
    "REGULARISATION",
    "SELECTIVITY_COLUMNS",
    "SEPARABLE_RATIO",
    "SEPARATION_DB",
    "ExcitationDesign",
    "design_drive",
    "modal_gains",
    "partner_stem",
    "resolve_targets",
    "set_lines",
    "sine_from_targets",
]
