r"""``copdea-fem statespace``: the coupled modal model as a real LTI system
``x' = A x + B u, y = C x + D u``.

Physical time convention ``e^{+i omega t}``, ``s = i omega`` (the FE's fields go as
``e^{-i omega t}``: a transfer here is the complex conjugate of the FE's).  Inputs: the AC
voltages ``u_k`` [V] of the inputs (:mod:`.modal_inputs`); outputs: the three Cartesian
velocity components [m/s] at the observed points (:func:`.modal_inputs.study_points`), the
sound pressure [Pa] at the study's microphones (``response.microphones``, with the outside
air; advanced by each one's propagation delay: :mod:`.modal_inputs` eq. 3), then each
input's motional current [A] (:mod:`.modal_inputs` eq. 2).

Modes as real states
--------------------
A band column's transfer (:mod:`.modal_inputs` eq. 1, conjugated) is

    conj(x_j) conj(p_jk) / (a s^2 + b s + c),
    a = conj(n_j), b = conj(lambda_j (b/m)_j m_j), c = conj(n_j lambda_j).            (1)

Its roots s1, s2: s1 the resonant one (``Im s1 > 0``, near ``i omega_j``; without damping
``s1 = i conj(omega_j)``, ``omega_j = sqrt(lambda_j)``, i.e. ``Re s1 = 2 pi Im f`` and
``Im s1 = 2 pi Re f`` of the mode's complex frequency f as ``solve`` writes it).  The partial
fraction ``g/(s - s1) - g/(s - s2)``, ``g = 1/(a (s1 - s2))``, holds the mode; its real
realisation keeps the resonant pole and adds its complex conjugate:

    z' = s1 z + g conj(p_jk) u_k,     displacement = 2 Re(conj(x_j) z)                (2)

with the real states ``(Re z, Im z)``: the block ``[[sigma, -w], [w, sigma]]``
(``s1 = sigma + i w``).  The velocity is ``2 Re(conj(x_j) (s1 z + g conj(p_jk) u))``.
Where the pencil is real (no air: real lambda, n, p, x) the conjugate of s1 *is* s2 and (2)
is exact; with the air's radiation and PML the far pole ``s2`` (near ``-i omega_j``, with
the wrong sign of damping) is replaced by the conjugate of s1: the realisation is stable,
its poles are the coupled eigenvalues of ``solve``, and it departs from the modal path by
the difference of that non-resonant term (order ``|Im f_j| / Re f_j`` of it).

Static correction
-----------------
The modes above the band contribute ``r0_k + omega^2 r1_k`` (harmonic module notes): a
displacement that follows the input.  Its velocity ``s r0 u`` is a pure differentiator, not a
proper output, so it cannot sit in D as such; it is kept as one extra pseudo-mode per input
(modal truncation augmentation): the residual shape ``r0_k`` with the eigenvalue
``Lambda_k`` that fits ``r1_k ~ r0_k / Lambda_k`` in least squares at the points
(``1/Lambda = r0^H r1 / r0^H r0``),

    r0_k Lambda_k / (Lambda_k - omega^2) = r0_k + omega^2 r0_k / Lambda_k + O(omega^4)  (3)

realised as a real pole pair ``s1, conj(s1)`` of unit static gain,

    r0_k |s1|^2 / ((s - s1)(s - conj(s1))),   residue |s1|^2 / (s1 - conj(s1)) in (2),   (4)

``s1`` the root of ``s^2 + conj(Lambda_k)`` taken in the stable half-plane and damped at
least :data:`PSEUDO_DAMPING` (a fitted Lambda is complex with the air, and a root with
``Re s1 > 0`` would make the system unstable; for a real Lambda and no damping (4) is (3)
exactly).  At ``s = 0`` the model's gain is the exact static response ``A^-1 F``.
D holds what a velocity realisation (2) feeds through (``2 Re(conj(x) g conj(p))``, zero
for a real pencil).  With the air, ``statespace`` takes the radiating band of the part a
uniform electrode drives (its air and PML modes up to ``response.modal_band f_max`` as
states: :func:`.modal_inputs.radiating_band`), microphone or not: with ``solve``'s band
alone the strongly damped PML modes were left to that part's static correction, its fitted
Lambda came out negative, and (4) lost the low end (measured on the quick G1 in a baffle,
undamped, a 110-degree segment: 155 % of the modal path's velocity at 50 Hz, 35 % at 300
Hz; with the band 0.4-1.7 %).

Columns that no input drives (the orders m >= 1 of a whole electrode) are left out: they
are not controllable.

Self-sensing current: the motional part ``F_k^T v`` (:mod:`.modal_inputs` eq. 2) only; the
blocked capacitance's ``C_k0 dV_k/dt`` is improper as an LTI output and is left to the user
(``units`` says so).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from copdea_fem.study import StudyError

logger = logging.getLogger(__name__)

#: The columns of the state-space arrays, as statespace.npz names them.
NPZ_KEYS = ("A", "B", "C", "D", "inputs", "outputs", "units", "states")

CURRENT_NOTE = ("motional current V_b dC_k/du . du/dt only; the blocked capacitance's "
                "C_k0 dV_k/dt (improper) is not in the model")


@dataclass
class StateSpaceModel:
    """A real LTI system ``x' = A x + B u, y = C x + D u`` (module notes).

    Attributes
    ----------
    A : (N, N) array [1/s]
    B : (N, K) array [state unit / (V s)]
    C : (Q, N) array
    D : (Q, K) array
    inputs : list of str
        The inputs' AC voltages ``V~_<name>`` [V].
    outputs : list of str
        ``v<x|y|z>_<point>`` [m/s], then ``p_<microphone>`` [Pa], then ``i_<input>`` [A].
    units : dict
        Name -> unit of every input and output (and ``current``: what the current holds).
    states : list of str
        ``<label or channel:column>.re|im`` per state (``residual:<channel>:<input>`` for the
        static correction's pseudo-modes).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: list
    outputs: list
    units: dict
    states: list

    def frequency_response(self, frequency_hz) -> np.ndarray:
        """``C (i omega - A)^-1 B + D`` (F, Q, K)."""
        frequency_hz = np.atleast_1d(np.asarray(frequency_hz, float))
        identity = np.eye(self.A.shape[0])
        return np.stack([self.C @ np.linalg.solve(2j * np.pi * f * identity - self.A, self.B)
                         + self.D for f in frequency_hz])

    def arrays(self) -> dict:
        """The npz/mat contents (:data:`NPZ_KEYS`): arrays and string arrays."""
        units = np.array([f"{name}: {unit}" for name, unit in self.units.items()])
        return {"A": self.A, "B": self.B, "C": self.C, "D": self.D,
                "inputs": np.array(self.inputs), "outputs": np.array(self.outputs),
                "units": units, "states": np.array(self.states)}

    def as_control(self):
        """A ``control.StateSpace`` (python-control, the optional extra ``control``), or
        ``None`` when python-control is not installed."""
        try:
            import control
        except ImportError:
            return None
        return control.StateSpace(self.A, self.B, self.C, self.D, inputs=list(self.inputs),
                                  outputs=list(self.outputs))


def pressure_note(model) -> str:
    """What the pressure outputs hold (``units["pressure"]``, :mod:`.modal_inputs` eq. 3):
    each microphone's pressure advanced by its propagation delay, which is left out."""
    delays = ", ".join(f"{name} {1e3 * delay:.4g} ms" for (name, _), delay in
                       zip(model.microphones, model.microphone_delays))
    return ("sound pressure at the microphone advanced by its propagation delay |x|/c "
            f"(a pure delay, not in the model: {delays}); each mode's radiation kernel to "
            "first order in the frequency, fitted over the band")


def resonant_root(a: complex, b: complex, c: complex) -> tuple[complex, complex]:
    """(s1, s2) of ``a s^2 + b s + c`` (1): s1 the root with the larger imaginary part."""
    roots = np.roots([a, b, c])
    roots = roots[np.argsort(-roots.imag)]
    return complex(roots[0]), complex(roots[1])


#: The least damping ratio of a pseudo-mode (4): its poles stand for modes far above the
#: band, so their damping is not physics; 1 % keeps them off the imaginary axis and changes
#: the correction in the band by about 2 zeta f / f_pseudo of itself.
PSEUDO_DAMPING = 0.01


def pseudo_pole(lam: complex) -> complex:
    """The pole s1 = sigma + i w of a pseudo-mode with the fitted eigenvalue ``lam``
    [rad^2/s^2] (3, 4): the root of ``s^2 + conj(lam)`` reflected into the stable upper-left
    quadrant, damped at least :data:`PSEUDO_DAMPING`."""
    root = np.sqrt(-np.conj(complex(lam)))
    w, radius = abs(root.imag), abs(root)
    sigma = -max(abs(root.real), PSEUDO_DAMPING * radius)
    return complex(sigma, np.sqrt(max(radius ** 2 - sigma ** 2, 0.0)) if w > 0 else w)


def check_statespace_study(study) -> None:
    """Refuse (StudyError) what the modal LTI cannot hold, before any solve."""
    from copdea_fem.forced_response.run import states_material_damping
    if study.load.voltage <= 0:
        raise StudyError("load.voltage = 0 is not allowed for `statespace`; allowed: > 0 V "
                         "(the linear forcing V_b dC/du vanishes without a bias)")
    if states_material_damping(study):
        membrane = study.membrane
        raise StudyError(
            f"membrane.loss_factor = {membrane.loss_factor:g}, rayleigh_alpha = "
            f"{membrane.rayleigh_alpha:g}, rayleigh_beta = {membrane.rayleigh_beta:g}, "
            f"prony = {membrane.prony!r} are not allowed for `statespace`; allowed: 0, 0, 0, "
            "none (the state space damps its modes with the paper's modal b/m, "
            "reduced.damping_*; a hysteretic loss has no real-time realisation)")


def statespace_microphones(study) -> list:
    """The microphones whose pressure ``statespace`` outputs (:func:`.run.parse_microphones`:
    the axis one and ``response.microphones``); none without the outside air (a dry study,
    ``air.outside = false``).  Refuses (StudyError) listed microphones with
    ``electrodes.segments``, as ``response`` does: the orders m >= 1 that segments drive
    radiate off the axis, and the model's sound is that of the order m = 0 alone."""
    from copdea_fem.forced_response.run import parse_microphones
    if not (study.air.enabled and study.air.outside):
        return []
    if study.electrodes.segments and study.response.microphones.strip():
        raise StudyError(f"response.microphones = {study.response.microphones!r} is not "
                         "allowed with electrodes.segments for `statespace`; allowed: '' (the "
                         "axis microphone alone: the orders m >= 1 a segmented drive reaches "
                         "radiate nothing onto the axis, and their sound elsewhere is not "
                         "computed)")
    return parse_microphones(study)


def realise(model, static_correction: bool = True) -> StateSpaceModel:
    """The real LTI system (module notes) of a :class:`.modal_inputs.ModalInputs`
    (``static_correction``: with the pseudo-modes (3) of the modes above the band)."""
    count = len(model.inputs)
    points = len(model.point_names)
    blocks, b_rows, c_cols, d_total, states = [], [], [], None, []

    microphones = len(model.microphones)

    def add(label, s1, input_row, velocity_shape, pressure_shape, current_shape):
        """One pole pair (2): ``input_row`` (K,) complex ``g conj(p)``; the output shapes
        the conjugated displacement (Q_v,), pressure kernel (3) (2, M) and charge (K,) per
        unit of z: the velocity and the current are ``s z`` times theirs, the pressure
        ``z`` times its kernel's constant and ``s z`` times its rate."""
        nonlocal d_total
        sigma, w = s1.real, s1.imag
        blocks.append(np.array([[sigma, -w], [w, sigma]]))
        b_rows.append(np.vstack([input_row.real, input_row.imag]))
        derivative = np.concatenate([velocity_shape, pressure_shape[1], current_shape])
        direct = np.concatenate([np.zeros(velocity_shape.size), pressure_shape[0],
                                 np.zeros(current_shape.size)])
        out = derivative * s1 + direct                    # s z = s1 z + input_row u
        c_cols.append(np.column_stack([2 * out.real, -2 * out.imag]))
        feed = 2 * np.real(derivative[:, None] * input_row[None, :])
        d_total = feed if d_total is None else d_total + feed
        states.extend([f"{label}.re", f"{label}.im"])

    for channel in model.channels:
        for j, lam in enumerate(channel.eigenvalues):
            if not np.any(channel.participation[j]):
                continue                        # no input drives it: not controllable
            a = np.conj(channel.norms[j])
            b = np.conj(channel.damping[j])
            c = np.conj(channel.norms[j] * lam)
            s1, s2 = resonant_root(a, b, c)
            g = 1.0 / (a * (s1 - s2))
            label = channel.labels[j] or f"{channel.name}:{j}"
            add(label, s1, g * np.conj(channel.participation[j]),
                np.conj(channel.displacement[..., j]).reshape(-1),
                np.conj([channel.pressure[:, j], channel.pressure_rate[:, j]]),
                np.conj(channel.currents[:, j]))
        for k in range(count if static_correction else 0):
            r0 = channel.residual_displacement[..., k].reshape(-1)
            r1 = channel.residual_displacement1[..., k].reshape(-1)
            q0, q1 = channel.residual_currents[:, k], channel.residual_currents1[:, k]
            both0, both1 = (r0, r1) if np.any(r0) else (q0, q1)
            scale = np.vdot(both0, both0)
            if abs(scale) == 0:
                continue
            inverse = np.vdot(both0, both1) / scale          # 1/Lambda (3)
            if not (abs(inverse) > 0 and (1 / inverse).real > 0):
                logger.warning(f"statespace: the static correction of {channel.name}, input "
                               f"{model.inputs[k]}, has no positive fitted eigenvalue; kept "
                               "as a pseudo-mode far above the band")
                inverse = 1e-6 * inverse if abs(inverse) > 0 else 0.0
            lam = 1 / inverse if abs(inverse) > 0 else 1e30
            s1 = pseudo_pole(lam)
            row = np.zeros(count, complex)
            row[k] = abs(s1) ** 2 / (s1 - np.conj(s1))          # (4): static gain 1
            add(f"residual:{channel.name}:{model.inputs[k]}", s1, row,
                np.conj(r0), np.conj([channel.residual_pressure[:, k],
                                      channel.residual_pressure_rate[:, k]]), np.conj(q0))
    size = 2 * len(blocks)
    a_matrix = np.zeros((size, size))
    for index, block in enumerate(blocks):
        a_matrix[2 * index:2 * index + 2, 2 * index:2 * index + 2] = block
    b_matrix = np.vstack(b_rows) if b_rows else np.zeros((0, count))
    rows = 3 * points + microphones + count
    c_matrix = np.hstack(c_cols) if c_cols else np.zeros((rows, 0))
    d_matrix = d_total if d_total is not None else np.zeros((rows, count))
    outputs = [f"v{axis}_{name}" for name in model.point_names for axis in "xyz"]
    outputs += [f"p_{name}" for name, _ in model.microphones]
    outputs += [f"i_{name}" for name in model.inputs]
    units = {f"V~_{name}": "V" for name in model.inputs}
    units.update({name: "m/s" for name in outputs if name.startswith("v")})
    units.update({f"p_{name}": "Pa" for name, _ in model.microphones})
    units.update({f"i_{name}": "A" for name in model.inputs})
    units["current"] = CURRENT_NOTE
    if model.microphones:
        units["pressure"] = pressure_note(model)
    return StateSpaceModel(a_matrix, b_matrix, c_matrix, d_matrix,
                           [f"V~_{name}" for name in model.inputs], outputs, units, states)


__all__ = ["CURRENT_NOTE", "NPZ_KEYS", "StateSpaceModel", "check_statespace_study",
           "pressure_note", "realise", "resonant_root", "statespace_microphones"]
