"""Modes of one circumferential order: classification, labels (m, n), the cos/sin pair.

Within an order m every quantity is an exact 1-D integral of the amplitudes (a, b, c)
(:mod:`.operators`): kinetic energies with ``M_s``, the normal part with ``M_n = Theta_m
rho_s int (a n_r + c n_z)^2 R dR`` (n the prestressed normal), the disc's share ``(M_d +
M_s/3) |w_d|^2 / x^H M x`` with its lumped mass. Kinds are decided as in the 3-D engine
(:mod:`copdea_fem.fe.modes`: the same thresholds); labels come by construction: m is the
order, n of an out-of-plane mode is its rank among the out-of-plane modes of the order
(n - 1 interior nodal circles), in-plane modes ``ip(m,n)`` take n from the nodal count
of their dominant in-plane component and pumping modes are ``P1, P2, ...`` as there.
Each m >= 1 mode is the pair (m,n)a (cos m theta) / (m,n)b (sin m theta, the same shape
turned by pi/(2m)) with one frequency; their ``sector`` is their parity about x = 0 and
y = 0 (:mod:`copdea_fem.fe.symmetry`), so modes.csv reads as the 3-D engine's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.acoustics import CAVITY
from copdea_fem.fe.axisymmetric.meridian import theta_integral
from copdea_fem.fe.axisymmetric.operators import normal_mass_form
from copdea_fem.fe.cavity import CAVITY_SHARE, label_cavity_modes, nodal_counts
from copdea_fem.fe.linearise import to_scipy
from copdea_fem.fe.modes import (
    AIR,
    IN_PLANE,
    OUT_OF_PLANE,
    OUT_OF_PLANE_FRACTION,
    PUMPING,
    PUMPING_DISC_FRACTION,
    Mode,
    assign_labels,
    may_be_cavity_mode,
    membrane_energy_fractions,
    number_from_dry_partners,
    radial_order,
)
from copdea_fem.fe.symmetry import Sector


@dataclass
class OrderMode(Mode):
    """A :class:`copdea_fem.fe.modes.Mode` of order ``m``: ``vector`` holds the coefficients of
    the order's (a, b, c) space; ``family`` is ``"cos"`` or ``"sin"``."""

    family: str = "cos"
    operators: object = None        # the OrderOperators the vector belongs to


def order_harmonics(m: int, family: str, angles, orientation: float = math.nan):
    """(radial/axial factor, hoop factor) of an order-m field at ``angles`` [rad].

    ``orientation`` [deg] (a member of a pair split by an imperfection,
    :mod:`.perturbation`; NaN: none): the field ``cos m (theta - orientation)``, hoop
    ``sin m (theta - orientation)``, whatever the family (the cos member at 0, the sin
    member at 90/m deg are the unsplit cases below).

    The cos family is ``u_r = a cos m theta, u_theta = b sin m theta, u_z = c cos m theta``,
    the sin family its copy turned by a quarter wave (``a sin, -b cos, c sin``).  At m = 0
    only the cos family exists and its hoop factor is 1, not ``sin 0 theta = 0``: the
    order-0 hoop motion (torsion, ``ip(0,n)``) is ``b(r)`` itself, and the (a, c) modes of
    order 0 carry no b.
    """
    if m and not math.isnan(orientation):
        phase = m * (angles - math.radians(orientation))
        return np.cos(phase), np.sin(phase)
    if family == "cos":
        return np.cos(m * angles), (np.sin(m * angles) if m else np.ones_like(angles))
    return np.sin(m * angles), -np.cos(m * angles)


def family_sector(m: int, family: str) -> Sector:
    """Parity about x = 0 and y = 0 of a cos / sin m theta normal displacement."""
    sign = 1 if m % 2 == 0 else -1
    return Sector(sign, 1) if family == "cos" else Sector(-sign, -1)


class OrderSampler:
    """(a, b, c) and the normal displacement of an order's vectors on the membrane line."""

    def __init__(self, state, space, axis_m1: bool):
        self.line = state.line()
        self.gf = ngs.GridFunction(space)
        a, second, c = self.gf.components
        b = second - a if axis_m1 else second
        normal = state.fields()["normal"]
        self._fields = ngs.CF((a * normal[0] + c * normal[1], a, b, c))
        self.radii = self.line.radii.ravel()
        order = np.argsort(self.radii, kind="stable")
        self._order, self.radii = order, self.radii[order]
        inner = max(state.inner_radius, 0.02 * state.outer_radius)
        self._uniform = inner + (state.outer_radius - inner) * (np.arange(40) + 0.5) / 40

    def radial_dominant(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the radial amplitude ``a`` carries at least the hoop one's ``b`` share,
        summed on the 3-D engine's uniform sample radii (:class:`copdea_fem.fe.modes.ModeSampler`:
        the same decision there)."""
        uniform = self._uniform

        def energy(part):
            return float(np.sum(np.abs(np.interp(uniform, self.radii, part.real)) ** 2
                                + np.abs(np.interp(uniform, self.radii, part.imag)) ** 2))

        return energy(a) >= energy(b)

    def components(self, vector) -> np.ndarray:
        """(normal, a, b, c) on the sorted sample radii: array (4, n_points)."""
        parts = []
        for part in (np.real(vector), np.imag(vector)) if np.iscomplexobj(vector) else (vector,):
            self.gf.vec.FV().NumPy()[:] = part
            parts.append(self.line.values(self._fields).reshape(-1, 4)[self._order].T)
        return parts[0] + 1j * parts[1] if len(parts) == 2 else parts[0]


def normal_mass_matrix(operators) -> object:
    """M_n of the order (SciPy, on the order space's DOFs) [kg]: set by
    :meth:`.operators.OrderForms.operators`, else assembled here on first use."""
    if operators.normal_mass is None:
        trial, test = operators.space.TnT()
        form = normal_mass_form(operators.state, trial, test, theta_integral(operators.m))
        operators.normal_mass = to_scipy(ngs.BilinearForm(form).Assemble().mat)
    return operators.normal_mass


def classify_order(operators, vectors, freq_hz, freq_im_hz, residuals,
                   sampler: OrderSampler | None = None) -> list[OrderMode]:
    """Eigenpairs of one order -> normalised, classified modes (cos family only)."""
    m = operators.m
    sampler = sampler or OrderSampler(operators.state, operators.space, operators.axis_m1)
    full = operators.to_full(vectors)
    normal_mass = normal_mass_matrix(operators)
    modes = []
    for k in range(full.shape[1]):
        reduced, vector = vectors[:, k], full[:, k]
        total = float(np.real(np.vdot(reduced, operators.mass @ reduced)))
        disc = complex(reduced[-1]) if operators.disc_dof else 0.0
        # the rigid disc's own (lumped) mass only, as copdea_fem.fe.modes: mass[-1, -1] also
        # holds the membrane mass the rim lift carries
        disc_energy = operators.disc_mass * abs(disc) ** 2
        normal_energy = float(np.real(np.vdot(vector, normal_mass @ vector)))
        normal_fraction = normal_energy / max(total - disc_energy, 1e-300)
        disc_fraction = disc_energy / max(total, 1e-300)
        normal, a, b, c = sampler.components(vector)
        if disc_fraction > PUMPING_DISC_FRACTION:
            kind, reference = PUMPING, abs(disc)
        elif normal_fraction >= OUT_OF_PLANE_FRACTION:
            kind, reference = OUT_OF_PLANE, float(np.abs(normal).max())
        else:
            kind, reference = IN_PLANE, float(np.abs([a, b]).max())
        radial_dominant = sampler.radial_dominant(a, b)
        in_plane = a if radial_dominant else b
        n = radial_order(in_plane) if kind == IN_PLANE else 0
        component = "" if kind != IN_PLANE else ("radial" if radial_dominant else "hoop")
        scale = 1.0 / reference if reference > 0 else 1.0
        peak = float(np.abs(np.stack([a, b, c])).max()) * scale
        modes.append(OrderMode(
            index=k, freq_hz=float(freq_hz[k]), freq_im_hz=float(freq_im_hz[k]),
            residual=float(residuals[k]), kind=kind, m=m, n=n, label="",
            normal_fraction=normal_fraction, disc_fraction=disc_fraction,
            modal_mass=total * scale**2, vector=vector * scale / max(peak, 1e-300),
            disc_displacement=disc * scale / max(peak, 1e-300),
            sector=family_sector(m, "cos"), family="cos", in_plane_component=component,
            operators=operators))
    return modes


def number_out_of_plane(modes: list[OrderMode]) -> None:
    """n of the out-of-plane modes of one order: their rank by frequency."""
    rank = 0
    for mode in sorted(modes, key=lambda mode: mode.freq_hz):
        if mode.kind == OUT_OF_PLANE:
            rank += 1
            mode.n = rank


def with_pairs(modes: list[OrderMode]) -> list[OrderMode]:
    """Every m >= 1 mode followed by its sin-family twin (same frequency, turned shape)."""
    paired = []
    for mode in modes:
        paired.append(mode)
        if mode.m > 0 and (mode.kind != AIR or mode.cavity_orders):
            paired.append(replace(mode, family="sin", sector=family_sector(mode.m, "sin")))
    return paired


def label_all(modes: list[OrderMode]) -> None:
    """Labels over all orders, as the 3-D engine's (:func:`copdea_fem.fe.modes.assign_labels`);
    a cavity mode (an air mode or a vent's Helmholtz mode, :class:`CavitySampler`) takes a
    cavity label, the other air modes are ``air``."""
    assign_labels([mode for mode in modes if mode.kind != AIR and not mode.cavity_orders])
    for mode in modes:
        if mode.kind == AIR:
            mode.label, mode.n = "air", 0
    label_cavity_modes(modes)


def number_from_dry(modes, dry_modes, mass) -> None:
    """n of the coupled out-of-plane modes of one order: their dry partner's
    (:func:`copdea_fem.fe.modes.number_from_dry_partners`), so that n counts from 0 Hz up
    (the dry band starts there) whatever band the coupled solve had.  Without dry
    out-of-plane modes (none below 1.5 f_max, or ``dry_modes`` None: none solved) the rank
    among the coupled ones stands."""
    number_out_of_plane([mode for mode in modes if not mode.cavity_orders])
    if dry_modes:
        number_from_dry_partners(modes, dry_modes, mass)


def numbered_dry_modes(operators, result, sampler=None) -> list:
    """The dry modes of one order's band ``result`` (solved from 0 Hz, :func:`.operators.dry_order`),
    classified and their out-of-plane n counted by rank: the dry partners that number the
    order's coupled modes (:func:`name_coupled_order`)."""
    modes = classify_order(operators, result.vectors, result.freq_hz, result.freq_im_hz,
                           result.residuals, sampler)
    number_out_of_plane(modes)
    return modes


def coupled_order_modes(coupled, result, min_membrane_energy: float, sampler=None):
    """Classify the coupled eigenpairs ``result`` of one order (``coupled``: its
    :class:`.operators.CoupledOrderOperators`), as
    :func:`copdea_fem.fe.modes.coupled_mode_list` does on the 3-D engine: (modes, pressure
    vectors [Pa, ``coupled.pressure_free`` DOFs, scaled as the modes' normalised vectors]);
    a mode whose membrane carries less than ``min_membrane_energy`` of the kinetic energy
    (:func:`copdea_fem.fe.modes.membrane_energy_fractions`) is an air mode."""
    dry = coupled.membrane
    membrane = result.vectors[coupled.membrane_index]
    modes = classify_order(dry, membrane, result.freq_hz, result.freq_im_hz,
                           result.residuals, sampler)
    full = dry.to_full(membrane)
    pressures = []
    for k, (mode, fraction) in enumerate(zip(modes, membrane_energy_fractions(coupled,
                                                                              result))):
        mode.membrane_energy_fraction = fraction
        if fraction < min_membrane_energy:
            mode.kind = AIR
        scale = np.linalg.norm(mode.vector) / max(np.linalg.norm(full[:, k]), 1e-300)
        pressures.append(result.vectors[coupled.pressure_index, k]
                         * coupled.pressure_scale * scale)
    return modes, pressures


def name_coupled_order(modes, pressures, dry_modes, coupled, cavity_sampler=None) -> None:
    """What one order's coupled modes are, before their labels (:func:`label_all`):
    the rule of ``solve``, which ``response`` applies to its order m = 0 too.

    A mode that moves mostly air (:func:`copdea_fem.fe.modes.may_be_cavity_mode`) whose air
    lies inside the enclosure takes its cavity orders (``cavity_sampler``, a
    :class:`CavitySampler`; None: an open back), a vent's Helmholtz mode
    ``cavity(0,0,0)`` among them; the out-of-plane modes take their dry partner's n
    (:func:`number_from_dry`, ``dry_modes`` of :func:`numbered_dry_modes`; None: their rank).

    ``pressures``: the modes' pressure vectors on ``coupled.pressure_free``
    (:func:`coupled_order_modes`).
    """
    if cavity_sampler is not None:
        for mode, pressure in zip(modes, pressures):
            if may_be_cavity_mode(mode):
                mode.cavity_orders = cavity_sampler.orders(coupled.membrane.m,
                                                           coupled.pressure_free, pressure)
    number_from_dry(modes, dry_modes, coupled.membrane.mass_full)


class CavitySampler:
    """The pressure of an order's modes inside an enclosure: the cavity's share of the air's
    potential energy and the (n, p) nodal counts (:mod:`copdea_fem.fe.cavity`).

    ``pressure_space``: the (p, q) space of :class:`.operators.MeridianAir`; the cavity's
    pressure is ``p + q`` (:func:`copdea_fem.fe.acoustics.pressure_space`), sampled on a
    grid of ``samples`` x ``samples`` points of its (r, z) section, the bottom followed.
    """

    def __init__(self, pressure_space, cavity, samples: int = 33):
        mesh = pressure_space.mesh
        self.function = ngs.GridFunction(pressure_space)
        p, q = self.function.components
        self.inside = p + q
        radii = cavity.radius * (np.arange(samples) + 0.5) / samples
        fractions = (np.arange(samples) + 0.5) / samples
        heights = fractions[None, :] * cavity.bottom(radii)[:, None]    # (radii, depths)
        self.shape = heights.shape
        self.points = mesh(np.repeat(radii, samples), heights.ravel())
        outside = "|".join(name for name in ("air_upper", "air_lower")
                           if name in mesh.GetMaterials())
        r = ngs.x
        self.inside_energy = ngs.Norm(self.inside) ** 2 * r * ngs.dx(CAVITY)
        self.outside_energy = (ngs.Norm(p) ** 2 * r * ngs.dx(outside)) if outside else None

    def _set(self, free_dofs, vector) -> None:
        values = self.function.vec.FV().NumPy()
        values[:] = 0
        values[free_dofs] = vector

    def orders(self, m: int, free_dofs, vector) -> tuple:
        """(m, n, p) of a cavity mode of order m (pressure ``vector`` on ``free_dofs``),
        () when most of its air's energy lies outside (module doc of
        :mod:`copdea_fem.fe.cavity`)."""
        self._set(free_dofs, vector)
        mesh = self.function.space.mesh
        inside = abs(ngs.Integrate(self.inside_energy, mesh))
        outside = 0.0 if self.outside_energy is None else abs(
            ngs.Integrate(self.outside_energy, mesh))
        if inside <= CAVITY_SHARE * (inside + outside):
            return ()
        section = np.asarray(self.inside(self.points)).reshape(self.shape)
        n, p = nodal_counts(section)
        return m, n, p


def sampled_shapes(state, modes, n_radii: int = 40, n_angles: int = 64) -> np.ndarray:
    """(normal, radial, hoop) of each mode on the normalised polar grid of
    :class:`copdea_fem.fe.modes.ModeSampler`, weighted by sqrt(r / r_o) (as the sweep's
    ``_sampled_shapes``): rows comparable across meshes and orders by MAC."""
    r_o, r_i = state.outer_radius, state.inner_radius
    inner = max(r_i, 0.02 * r_o)
    radii = inner + (r_o - inner) * (np.arange(n_radii) + 0.5) / n_radii
    angles = 2 * np.pi * np.arange(n_angles) / n_angles
    weights = np.sqrt(radii / r_o)[:, None]
    rows, samplers = [], {}
    for mode in modes:
        operators = mode.operators
        key = id(operators)
        if key not in samplers:
            samplers[key] = OrderSampler(state, operators.space, operators.axis_m1)
        sampler = samplers[key]
        normal, a, b, c = sampler.components(mode.vector)
        profiles = [np.interp(radii, sampler.radii, part.real) + 1j * np.interp(
            radii, sampler.radii, part.imag) for part in (normal, a, b)]
        main, cross = order_harmonics(mode.m, mode.family, angles, mode.orientation)
        field_ = np.stack([profiles[0][:, None] * main, profiles[1][:, None] * main,
                           profiles[2][:, None] * cross]) * weights[None]
        rows.append(field_.ravel())
    return np.array(rows) if rows else np.zeros((0, 3 * n_radii * n_angles))
