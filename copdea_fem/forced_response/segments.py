r"""What each segment of a split electrode drives: the modal forces of ``modal_forcing.csv``
and the response of the segments driven at once.

The segment k driven alone by its AC voltage ``V~_k`` forces the membrane by
``f_k V~_k`` [N], ``f_k`` [N/V] the forcing of its indicator as a weight on the co-energy
(:mod:`copdea_fem.fe.forced.electrode`, :meth:`copdea_fem.fe.engines.Engine.electrode_forcing`):
on the axisymmetric engine the order-m forcing of ``1_r(R) cos(m theta)`` times the
segment's Fourier factors ``c_m``, ``s_m`` on the cos and sin families; on the 3-D quadrant
the forcing of the weight folded onto each symmetry sector.

**Modal force** (``modal_forcing.csv``).  For a structural mode j of the solve with
membrane (and disc) displacement ``u_j`` (the right eigenvector's structural part on the
part's unknowns), mass-normalised on the structural mass of the whole device,

    phi_j = u_j / sqrt(u_j^T M_s u_j),      Q_jk = phi_j^T f_k                       (1)

[N/(V sqrt(kg))]: the generalised force per volt of the segment's AC input on the modal
coordinate ``q_j`` [sqrt(kg) m] of ``u = sum_j phi_j q_j``, whose equation in vacuo is
``q_j'' + omega_j^2 q_j = Q_jk V~_k``.  The transposes are bilinear, not Hermitian (the
coupled modes are complex; for the dry, real modes (1) is the usual mass normalisation).
Its sign (phase) follows the mode's: each ``u_j`` is first turned so that its largest
entry is real and positive.  The quadrant's forms are a quarter of the device's (its mass
and its forcing), so (1) on a sector is twice the quadrant's ``u^T f / sqrt(u^T M u)``.

The twins of an axisymmetric pair (``family`` cos and sin) share their order's vector:
the cos twin's modal force is ``c_m`` times that of the order's forcing, the sin twin's
``s_m`` times it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from copdea_fem.forced_response.scan import part_modes

logger = logging.getLogger(__name__)

#: Columns of modal_forcing.csv (a contract).
MODAL_FORCING_COLUMNS = ("segment", "label", "freq_hz", "force_re", "force_im")


@dataclass(frozen=True)
class ModalForce:
    """One row of ``modal_forcing.csv``: the modal force (1) of a mode per volt of a
    segment's AC input.

    Attributes
    ----------
    segment : str
        The segment's name.
    label : str
        The mode's label as ``solve`` gives it.
    freq_hz : float
        The mode's frequency Re f [Hz].
    force : complex
        Q_jk [N/(V sqrt(kg))] (module notes, eq. 1).
    """

    segment: str
    label: str
    freq_hz: float
    force: complex


def normalised_structural(part, vectors) -> np.ndarray:
    """The mass-normalised structural parts ``phi_j`` [1/sqrt(kg)] of a part's band vectors
    (module notes, eq. 1; on a 3-D symmetry sector normalised on the whole device's mass,
    four times the quadrant's)."""
    pencil = part.pencil
    structural = np.asarray(vectors, complex)[np.asarray(pencil.membrane_index)]
    largest = np.argmax(np.abs(structural), axis=0)
    turn = np.conj(structural[largest, np.arange(structural.shape[1])])
    structural = structural * (turn / np.abs(turn))[None, :]
    mass = np.einsum("ij,ij->j", structural, pencil.membrane.mass @ structural)
    if part.sector is not None:          # the quadrant's forms are a quarter of the device's
        mass = 4.0 * mass
    return structural / np.sqrt(mass)[None, :]


def modal_forcing(solution, study, weights) -> list[ModalForce]:
    """The modal force (1) of every labelled structural mode of ``solution`` per volt of
    each segment of ``weights``, in the order of the weights, then of the modes' frequency.

    Parameters
    ----------
    solution : copdea_fem.fe.SolveResult
        The solve of ``study`` (either engine; its ``engine`` forces it).
    study : Study
    weights : list of (str, weight, complex)
        The segments (:func:`copdea_fem.fe.forced.electrode.segment_weights`); their drives
        are not used (the force is per volt of each segment's own input).

    Returns
    -------
    list of ModalForce
    """
    engine, state = solution.engine, solution.state
    rows: dict[str, list[ModalForce]] = {name: [] for name, _, _ in weights}
    for part in engine.driven_parts(solution, study):
        columns = part_modes(part, solution.modes)
        if not columns:
            continue
        phi = normalised_structural(part, part.band.vectors)
        forcings: dict = {}
        for name, weight, _ in weights:
            families = dict(part.families(weight)) if part.m is not None else {"cos": 1.0}
            if not families:
                continue
            key = (getattr(weight, "radii", None) if part.m is not None else id(weight))
            if key not in forcings:          # the orders' forcing depends on rho(R) alone
                forcings[key] = np.asarray(engine.electrode_forcing(state, part, weight),
                                           complex)
            projected = phi.T @ forcings[key]
            scale = 4.0 if part.sector is not None else 1.0      # quarter forcing (notes)
            for column, modes in columns.items():
                for mode in modes:
                    family = mode.family if part.m is not None else "cos"
                    if family not in families:
                        continue
                    rows[name].append(ModalForce(name, mode.label, float(mode.freq_hz),
                                                 complex(scale * families[family]
                                                         * projected[column])))
        logger.debug("modal forcing: %s (%d modes)", part.key, len(columns))
    return [row for name in rows for row in sorted(rows[name], key=lambda r: r.freq_hz)]


__all__ = ["MODAL_FORCING_COLUMNS", "ModalForce", "modal_forcing", "normalised_structural"]
