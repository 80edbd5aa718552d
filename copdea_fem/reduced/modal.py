"""Dry modes of the ring model and their labels (Sect. 3.2.2, eqs 15-18).

``K_s q = omega^2 M_s q`` (eq. 15) is solved densely (2n - 1 unknowns) with
mass-normalised eigenvectors, ``Q^T M_s Q = I`` and ``Q^T K_s Q =
diag(omega^2)`` (eq. 16).  Modes are sorted by frequency and their sign is
fixed (the largest-magnitude entry is positive), so results are
deterministic.

Labels follow the paper's figures (Sect. 4.3, Fig. 7): ``P1`` is the pumping
mode, the one whose kinetic energy sits most in the disc (only when the disc
rides on the spring); the others are split by where their membrane kinetic
energy goes -- normal to the equilibrium meridian (out-of-plane,
``(0,1), (0,2), ...`` in frequency order) or along it (in-plane,
``IP1, IP2, ...``).  At z = 0 the two families decouple exactly (normal =
axial, tangent = radial).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from copdea_fem.reduced.rings import Linearisation, ReducedModelError, RingModel


@dataclass(frozen=True)
class Mode:
    """One dry mode of the ring model (eq. 15).

    Attributes
    ----------
    label : str
        ``"P1"``, ``"(0,n)"`` or ``"IPn"``.
    kind : str
        ``"pumping"``, ``"out-of-plane"`` or ``"in-plane"`` (the modes.json kinds).
    frequency_hz : float
        Dry natural frequency omega / 2 pi [Hz] (eq. 15).
    shape : ndarray
        Mass-normalised eigenvector over the generalised coordinates
        (q^T M_s q = 1 kg m^2, i.e. entries in m / sqrt(kg)).
    radial, axial : ndarray, shape (n + 1,)
        The same shape as node displacements u_r, u_z (zeros at fixed nodes).
    disc_fraction : float
        Share of the kinetic energy in the disc, M_d u_z,n^2 [-].
    normal_fraction : float
        Share of the membrane's kinetic energy normal to the equilibrium
        meridian [-].
    nodal_circles : int
        Sign changes of the normal displacement over the interior nodes
        (n - 1 for mode (0,n) when the rings resolve it).
    """

    label: str
    kind: str
    frequency_hz: float
    shape: np.ndarray
    radial: np.ndarray
    axial: np.ndarray
    disc_fraction: float
    normal_fraction: float
    nodal_circles: int

    @property
    def angular_frequency(self) -> float:
        """omega [rad/s]."""
        return 2 * np.pi * self.frequency_hz

    @property
    def largest_displacement(self) -> float:
        """max |u| over all nodes and both components for the mass-normalised shape."""
        return float(max(np.max(np.abs(self.radial)), np.max(np.abs(self.axial))))


@dataclass(frozen=True)
class ModalBasis:
    """All 2n - 1 (or 2n - 2) dry modes at one operating point (eqs 15-16)."""

    linearisation: Linearisation
    modes: tuple

    @property
    def labels(self) -> tuple:
        return tuple(mode.label for mode in self.modes)

    def __getitem__(self, label: str) -> Mode:
        for mode in self.modes:
            if mode.label == label:
                return mode
        raise ReducedModelError(f"mode {label!r} is not among the ring model's modes "
                                f"({', '.join(self.labels)}); allowed: one of those -- "
                                "raise reduced.rings for higher (0,n)")

    def truncate(self, labels) -> tuple:
        """The modes of eq. (18) in the requested order."""
        return tuple(self[label] for label in labels)


def meridian_normals(radii, heights):
    """Unit tangent (dr, dz) and normal (-dz, dr) of the profile at each node [-].

    The tangent at an interior node is the mean of its two segments' unit
    tangents; end nodes take their only segment.
    """
    seg = np.stack([radii[:-1] - radii[1:], heights[:-1] - heights[1:]], axis=1)
    seg /= np.linalg.norm(seg, axis=1)[:, None]
    tangent = np.empty((len(radii), 2))
    tangent[0], tangent[-1] = seg[0], seg[-1]
    tangent[1:-1] = seg[:-1] + seg[1:]
    tangent /= np.linalg.norm(tangent, axis=1)[:, None]
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    return tangent, normal


def modal_decomposition(model: RingModel, linearisation: Linearisation) -> ModalBasis:
    """Solve eq. (15), normalise (eq. 16), fix signs and label every mode.

    Raises
    ------
    ReducedModelError
        K_s is not positive definite (an unstable operating point: the
        linearised model of Sect. 3.2 has no real frequencies there).
    """
    eigenvalues, vectors = scipy.linalg.eigh(linearisation.stiffness_matrix,
                                             linearisation.mass_matrix)
    if eigenvalues[0] <= 0:
        eq = linearisation.equilibrium
        raise ReducedModelError(
            f"load.z = {eq.disc_position:g} m, load.voltage = {eq.voltage:g} V is not allowed: "
            f"K_s is not positive definite (smallest eigenvalue {eigenvalues[0]:.3g} 1/s^2), "
            "the operating point is unstable; allowed: a stable equilibrium")
    eq = linearisation.equilibrium
    tangent, normal = meridian_normals(eq.radii, eq.heights)
    node_mass = model.node_mass_matrix()
    disc_row = list(model.free_dofs).index(model.disc_dof) if model.disc_free else None
    raw = []
    for index in range(len(eigenvalues)):
        vector = vectors[:, index]
        pivot = int(np.argmax(np.abs(vector)))
        vector = vector if vector[pivot] > 0 else -vector
        radial, axial = model.expand(vector)
        u_n = normal[:, 0] * radial + normal[:, 1] * axial
        u_t = tangent[:, 0] * radial + tangent[:, 1] * axial
        e_n, e_t = u_n @ node_mass @ u_n, u_t @ node_mass @ u_t
        interior = u_n[1:-1]
        significant = interior[np.abs(interior) > 1e-6 * np.max(np.abs(u_n), initial=0.0)]
        raw.append(dict(shape=vector, radial=radial, axial=axial,
                        frequency_hz=float(np.sqrt(eigenvalues[index]) / (2 * np.pi)),
                        disc_fraction=(float(model.disc_mass * vector[disc_row] ** 2)
                                       if disc_row is not None else 0.0),
                        normal_fraction=float(e_n / (e_n + e_t)) if e_n + e_t > 0 else 0.0,
                        nodal_circles=int(np.sum(np.diff(np.sign(significant)) != 0))))
    pumping = (int(np.argmax([m["disc_fraction"] for m in raw]))
               if model.disc_free else None)
    modes, out_count, in_count = [], 0, 0
    for index, data in enumerate(raw):
        if index == pumping:
            label, kind = "P1", "pumping"
        elif data["normal_fraction"] >= 0.5:
            out_count += 1
            label, kind = f"(0,{out_count})", "out-of-plane"
        else:
            in_count += 1
            label, kind = f"IP{in_count}", "in-plane"
        modes.append(Mode(label=label, kind=kind, **data))
    return ModalBasis(linearisation=linearisation, modes=tuple(modes))


def mode_profile(model: RingModel, linearisation: Linearisation, mode: Mode) -> dict:
    """Mode shape as radial/axial displacement along the membrane (Fig. 9d).

    Returns a dict of node arrays: ``reference_radius`` R [m] (flat
    pre-stretched), ``radius``/``height`` of the equilibrium profile [m], and
    ``radial``/``axial`` displacement [-] scaled so that the largest |u| is 1
    (linear in between, as eq. 12 assumes).
    """
    scale = mode.largest_displacement
    eq = linearisation.equilibrium
    return {"reference_radius": model.reference_radii, "radius": eq.radii,
            "height": eq.heights, "radial": mode.radial / scale, "axial": mode.axial / scale}
