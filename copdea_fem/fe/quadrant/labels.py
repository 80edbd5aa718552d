"""How the 3-D engine names its coupled modes: the rule ``solve`` applies to every symmetry
sector and ``response`` to its even-even sector (:mod:`copdea_fem.fe.quadrant.forced`), so
that both give one mode one name.

A mode that moves mostly air and lives in the enclosure takes its cavity orders
(:func:`label_cavity_orders`: a vent's Helmholtz mode is ``cavity(0,0,0)``); over an
enclosure the m = 0 membrane modes take the n of their dry partners
(:func:`number_volume_modes`, the dry modes of :func:`sector_dry_modes`); then the labels
(:func:`name_coupled_modes`).
"""

from __future__ import annotations

from copdea_fem.fe.bands import BandSolver
from copdea_fem.fe.cavity import label_cavity_modes
from copdea_fem.fe.linearise import operator_damping
from copdea_fem.fe.modes import (
    AIR,
    OUT_OF_PLANE,
    ModeSampler,
    assign_labels,
    classify_modes,
    may_be_cavity_mode,
    number_from_dry_partners,
    sector_family,
)


def label_cavity_orders(sampler, sector, coupled, modes, pressures) -> None:
    """Give the modes of one sector that move mostly air
    (:func:`copdea_fem.fe.modes.may_be_cavity_mode`) and live in the enclosure their orders
    (:attr:`copdea_fem.fe.modes.Mode.cavity_orders`, :mod:`copdea_fem.fe.quadrant.cavity`):
    a round enclosure's (m, n, p) with m as the mode's order and its cos/sin member from
    the mirror class; a box's (i, j, k) (its nodal planes, no pair)."""
    taken = set()
    for mode, pressure in zip(modes, pressures):
        if not may_be_cavity_mode(mode):
            continue
        mode.cavity_orders = sampler.orders(sector, coupled.pressure_free, pressure)
        if not mode.cavity_orders:
            continue
        if sampler.spec.enclosure == "box":
            i, j, k = mode.cavity_orders
            # a square box's (i, j, k) and (j, i, k) in one sector: their sum and difference
            # (copdea_fem.fe.quadrant.cavity), which overlap both alike: the second is (j, i, k)
            if (i, j, k) in taken:
                mode.cavity_orders = (j, i, k)
            taken.add(mode.cavity_orders)
            mode.family = ""              # (i, j, k) names the mode whole: no pair letter
        else:
            mode.m = mode.cavity_orders[0]
            mode.family = "" if sector is None else sector_family(mode.m, sector)


def number_volume_modes(modes, dry, mass) -> None:
    """n of the coupled m = 0 out-of-plane modes over an enclosure: their dry partners'
    (:func:`copdea_fem.fe.modes.number_from_dry_partners`), sector by sector, as the
    axisymmetric engine numbers every order.  Only m = 0 changes the trapped volume, so only
    its shapes change enough under the air spring for a nodal count to misname them (the
    stiffened (0,1) gains a nodal circle); the m >= 1 keep their counted n.  A band whose
    dry modes of a sector miss the (0,1) (f_min above it) keeps the counted n too."""
    for sector in {mode.sector for mode in modes}:
        wet = [mode for mode in modes if mode.sector == sector and mode.m == 0]
        partners = [mode for mode in dry if mode.sector == sector and mode.m == 0
                    and mode.kind == OUT_OF_PLANE]
        if any(mode.n == 1 for mode in partners):
            number_from_dry_partners(wet, partners, mass)


def name_coupled_modes(modes, dry, mass) -> None:
    """Labels of coupled modes whose cavity orders are set (:func:`label_cavity_orders`,
    sector by sector): the rule of ``solve``, which ``response`` applies to its even-even
    sector too.  Over an enclosure (``dry``: the dry partners of the same sectors, None
    without one) the m = 0 out-of-plane modes take their dry partner's n
    (:func:`number_volume_modes`; ``mass``: the full membrane mass M_s [kg] of
    :func:`copdea_fem.fe.linearise.membrane_matrices`); the structural modes then take their
    (m,n) labels (:func:`copdea_fem.fe.modes.assign_labels`) and the cavity modes theirs
    (:func:`copdea_fem.fe.cavity.label_cavity_modes`)."""
    if dry is not None:
        number_volume_modes(modes, dry, mass)
    assign_labels([mode for mode in modes if mode.kind != AIR and not mode.cavity_orders])
    label_cavity_modes(modes)


def sector_dry_modes(operators, study, f_min: float, f_max: float, sampler=None) -> list:
    """The dry modes of one sector's :class:`copdea_fem.fe.linearise.MembraneOperators` in
    [f_min, f_max] [Hz] (the study's damping keys: :func:`copdea_fem.fe.linearise.operator_damping`),
    classified (:func:`copdea_fem.fe.modes.classify_modes`): the dry partners of its coupled
    modes."""
    result = BandSolver.from_study(study).solve(operators.stiffness, operators.mass, f_min,
                                                f_max, damping=operator_damping(operators, study))
    return classify_modes(operators, result, sampler or ModeSampler(operators.state))
