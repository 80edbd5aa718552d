r"""What the forced-response driver hands its observers, and the observers.

The driver (:func:`copdea_fem.forced_response.run.forced_response` for the uniform electrode
of ``copdea-fem response``, :func:`copdea_fem.forced_response.scan.scan_response` for an
imperfect one at a vibrometer's points) forces a driven part of the problem
(:class:`copdea_fem.fe.forced.problem.OrderZero`, :class:`copdea_fem.fe.DrivenPart`) and
solves it on the lines: a :class:`LineResponse`, the part's solution of each line as
``x(line) = vectors @ weights[line]``.  An observer reads what it measures from it:

- :class:`Microphones`: the sound pressure [Pa] at the microphones, by the Kirchhoff-
  Helmholtz (Rayleigh in a baffle) integral over the sphere sampler of the driven part
  (:mod:`copdea_fem.fe.forced.radiation`), or inside that sphere (near the device, inside
  an enclosure) the FE's own pressure field (:mod:`.microphone_places`);
- :class:`ScanPoints`: the displacement [m] at scan points of the prestressed device, along
  any of a part's fields (the engine's point sampler,
  :meth:`copdea_fem.fe.engines.Engine.point_sampler`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from copdea_fem.fe.forced.harmonic import CoupledPencil, ForcedOrder


@dataclass
class LineResponse:
    """A driven part's forced response on the lines.

    Attributes
    ----------
    forced : copdea_fem.fe.forced.harmonic.ForcedOrder
        The part's forced pencil (its membrane and pressure blocks).
    vectors : (n, K) array
        Basis vectors on the pencil's unknowns (modal, reduced or direct solutions).
    weights : (lines, K) array
        ``x(line) = vectors @ weights[line]`` [per volt of the part's forcing times the
        line's drive].
    """

    forced: ForcedOrder
    vectors: np.ndarray
    weights: np.ndarray

    def membrane(self) -> np.ndarray:
        """The basis vectors' membrane block (the part's membrane unknowns, the disc last)."""
        return self.forced.membrane(self.vectors)

    def pressure(self) -> np.ndarray:
        """The basis vectors' pressure block [Pa per unit of the vectors]."""
        return self.forced.pressure(self.vectors)


class Microphones:
    """The sound pressure at named microphones from a driven part's pressure field.

    Parameters
    ----------
    sphere : type
        The driven part's Kirchhoff sphere sampler
        (:attr:`copdea_fem.fe.forced.problem.DrivenSector.sphere`).
    coupled : copdea_fem.fe.forced.harmonic.CoupledPencil
        The part's coupled operators.
    microphones : list of (str, (3,) array)
        Name and position [m] of each microphone.
    radius : float
        The Kirchhoff sphere's radius [m].
    baffle : bool
        The frame is an infinite baffle (Rayleigh: each microphone sees its own side).
    enclosed : bool
        An enclosure closes the back (a baffle's front only).
    sound_speed : float
        [m/s]
    places : list of str, optional
        Per microphone, :data:`~copdea_fem.forced_response.microphone_places.FAR` (the
        integral; the default for all) or ``FIELD``: inside the sphere, the FE's own
        pressure at the point (:class:`~copdea_fem.forced_response.microphone_places.
        FieldPressure`: the air near the device or inside an enclosure).
    """

    def __init__(self, sphere, coupled: CoupledPencil, microphones, radius: float, baffle: bool,
                 enclosed: bool, sound_speed: float, places=None):
        from copdea_fem.forced_response.microphone_places import FIELD, FieldPressure

        self.microphones, self.baffle, self.sound_speed = microphones, baffle, sound_speed
        self.in_field = [place == FIELD for place in (places or [])] + \
            [False] * (len(microphones) - len(places or []))
        self.field = FieldPressure(coupled, [position for (_, position), inside in
                                             zip(microphones, self.in_field) if inside]) \
            if any(self.in_field) else None
        # a baffle over an enclosure has no air below it (microphones there refused:
        # study/checks.py)
        below = () if enclosed else ("lower",)
        self.samplers = ({"upper": sphere(coupled, radius, ("upper",)),
                          **{side: sphere(coupled, radius, (side,)) for side in below}}
                         if baffle else {"all": sphere(coupled, radius)})

    def observe(self, response: LineResponse, frequency_hz) -> np.ndarray:
        """Complex pressure amplitude [Pa] (lines, microphones) of ``response``."""
        omega = 2 * np.pi * np.asarray(frequency_hz, float)
        pressure_vectors = response.pressure()
        sampled = {name: sampler.sample(pressure_vectors)
                   for name, sampler in self.samplers.items()}
        weights = response.weights
        pressure = np.zeros((omega.size, len(self.microphones)), complex)
        if self.field is not None:
            inside = np.flatnonzero(self.in_field)
            pressure[:, inside] = weights @ self.field.sample(pressure_vectors).T
        for j, sampler, (p_values, dp_values) in self._far(sampled):
            field_p, field_dp = weights @ p_values.T, weights @ dp_values.T  # (lines, points)
            for line, w in enumerate(omega):
                kp, kg = sampler.kernels(self.microphones[j][1], w / self.sound_speed,
                                         self.baffle)
                pressure[line, j] = kp @ field_p[line] - kg @ field_dp[line]
        return pressure

    def column_pressure(self, response: LineResponse, frequency_hz) -> np.ndarray:
        """Complex pressure [Pa per unit of each vector] (F, microphones, K) of each of
        ``response.vectors`` at each frequency [Hz] (its weights are not used): the sphere
        sampled once, the kernels once per frequency."""
        omega = 2 * np.pi * np.atleast_1d(np.asarray(frequency_hz, float))
        pressure_vectors = response.pressure()
        sampled = {name: sampler.sample(pressure_vectors)
                   for name, sampler in self.samplers.items()}
        pressure = np.zeros((omega.size, len(self.microphones), pressure_vectors.shape[1]),
                            complex)
        if self.field is not None:
            pressure[:, np.flatnonzero(self.in_field)] = self.field.sample(pressure_vectors)
        for j, sampler, (p_values, dp_values) in self._far(sampled):
            for line, w in enumerate(omega):
                kp, kg = sampler.kernels(self.microphones[j][1], w / self.sound_speed,
                                         self.baffle)
                pressure[line, j] = kp @ p_values - kg @ dp_values
        return pressure

    def _far(self, sampled):
        """(microphone index, its side's sphere sampler, that side's (p, dp/drho) samples)
        of each microphone the integral reaches (z != 0 in a baffle: checks.py)."""
        for j, (_, position) in enumerate(self.microphones):
            if self.in_field[j]:
                continue
            side = ("upper" if position[2] > 0 else "lower") if self.baffle else "all"
            yield j, self.samplers[side], sampled[side]


class ScanPoints:
    """The displacement at scan points of the prestressed device, summed over the driven
    parts' fields.

    Parameters
    ----------
    sampler : copdea_fem.fe.points.PointSampler
        The engine's fields at the points (:meth:`copdea_fem.fe.engines.Engine.point_sampler`).
    lines : int
        Number of lines.

    Attributes
    ----------
    displacement : (P, 3, lines) complex array
        The Cartesian displacement [m per volt] summed so far.
    """

    def __init__(self, sampler, lines: int):
        self.sampler = sampler
        self.displacement = np.zeros((len(sampler.positions), 3, lines), dtype=complex)

    def basis(self, response: LineResponse, operators, family: str = "cos") -> np.ndarray:
        """The displacement (P, 3, K) of each basis vector of ``response`` at the points, as
        the ``family`` field of the part whose membrane operators are ``operators``."""
        membrane = response.membrane()
        full = operators.to_full(membrane)
        disc = membrane[-1] if operators.disc_dof else np.zeros(membrane.shape[1])
        return np.stack([self.sampler.field_displacement(
            full[:, k], disc[k], operators=operators, family=family)
            for k in range(full.shape[1])], axis=-1)

    def add(self, response: LineResponse, sampled: np.ndarray, factor: float = 1.0) -> None:
        """Add ``factor`` times the lines of ``response`` whose basis is ``sampled``
        (:meth:`basis`)."""
        self.displacement += factor * np.einsum("pdk,fk->pdf", sampled, response.weights)
