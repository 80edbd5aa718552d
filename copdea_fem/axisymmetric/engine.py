"""The axisymmetric engine's stages: meridian mesh -> prestress -> orders m -> modes.

Orders are solved m = 0, 1, 2, ... until one has no mode in the band: the
dry partner band of an order is solved to 1.5 f_max (as the 3-D engine does)
and the orders stop at the first m whose dry band is empty below 1.5 f_max
and whose coupled band holds no structural mode (the lowest frequency of an
order rises with m; an added mass above 125 % of a modal mass would be needed
for a wet mode below f_max with its dry partner above 1.5 f_max).
"""

from __future__ import annotations

import numpy as np

from ..eigen import SectorBandResults
from ..eigen.damped import solve_structural_band
from ..modes import AIR, match_dry, membrane_energy_fractions
from .air import meridian_motion
from .meridian import MeridianSpec, meridian_mesh
from .modes import (OrderSampler, classify_order, label_all, number_out_of_plane,
                    with_pairs)
from .operators import MeridianAir, OrderForms, coupled_order_operators
from .prestress import make_axisymmetric_solver

#: Highest order tried before giving up (a band this rich is a mistake in the study).
MAX_ORDER = 400


def _quiet(message: str) -> None:
    pass


def prepare_meridian(study, progress=_quiet):
    """The meridian mesh of the study (not cached: Netgen meshes it in ~0.1 s)."""
    return meridian_mesh(MeridianSpec.from_study(study), study["mesh"]["curve_order"], progress)


def solve_axisymmetric_prestress(study, mesh, progress=_quiet, solver=None):
    from ..prestress import solve_prestress
    solver = solver or make_axisymmetric_solver(study, mesh, progress)
    return solve_prestress(study, mesh, progress=progress, solver=solver)


def _prestressed(study, mesh, progress, timings, solver):
    """The mesh and prestress stages (the mesh made unless given)."""
    if mesh is None:
        with timings.stage("mesh"):
            mesh = prepare_meridian(study, progress)
    with timings.stage("prestress"):
        progress("prestress (axisymmetric Newton, load steps in z then V_b) ...")
        return solve_axisymmetric_prestress(study, mesh, progress, solver)


def _band(study, hermitian=True, **extra):
    eigen = study["eigen"]
    return dict(backend=eigen["backend"], max_modes=eigen["max_modes"],
                residual_tol=eigen["residual_tol"], hermitian=hermitian, **extra)


def _dry_order(study, forms, m, f_max, progress, initial_shifts=None):
    operators = forms.operators(m)
    # damping keys: the quadratic/rational step in omega (eigen.damped), else linear
    result = solve_structural_band(
        operators.stiffness, operators.mass, study["eigen"]["f_min"], f_max,
        forms.damping(operators), damped_imag_hz=study["eigen"]["max_damping_ratio"] * f_max,
        progress=progress, initial_shifts=initial_shifts, **_band(study))
    return operators, result


def axisymmetric_dry_modes(study, mesh=None, progress=_quiet, timings=None, solver=None,
                           initial_shifts=None):
    """Prestress and dry modes in the band, order by order: (state, modes, results)."""
    from ..solve import Timings
    timings = timings or Timings()
    eigen = study["eigen"]
    state = _prestressed(study, mesh, progress, timings, solver)
    modes, results = [], {}
    initial_shifts = initial_shifts or {}
    forms = OrderForms(state, study)
    for m in range(MAX_ORDER + 1):
        with timings.stage("eigen"):
            operators, result = _dry_order(study, forms, m, eigen["f_max"],
                                           lambda text: progress(f"m = {m}: {text}"),
                                           initial_shifts.get(f"m={m}"))
        if len(result) == 0:
            break
        results[f"m={m}"] = result
        with timings.stage("classify"):
            order_modes = classify_order(operators, result.vectors, result.freq_hz,
                                         result.freq_im_hz, result.residuals)
            number_out_of_plane(order_modes)
            modes += with_pairs(order_modes)
    modes.sort(key=lambda mode: (mode.freq_hz, mode.m, mode.family))
    for index, mode in enumerate(modes):
        mode.index = index
    label_all(modes)
    return state, modes, SectorBandResults(results)


def same_order_family(mode, dry) -> bool:
    """Pairing rule within one order: same kind and (out-of-plane) the same n."""
    return dry.kind == mode.kind and (mode.kind == "in-plane" or dry.n == mode.n)


def axisymmetric_coupled_modes(study, mesh=None, progress=_quiet, timings=None, solver=None,
                               initial_shifts=None):
    """Prestress, dry partners and fully-coupled membrane-air modes, order by order.

    Returns a :class:`copdea_fem.solve.CoupledSolution` (``operators``: the
    coupled pencil of each order, in order).
    """
    from ..solve import CoupledSolution, Timings
    timings = timings or Timings()
    eigen, air = study["eigen"], study["air"]
    state = _prestressed(study, mesh, progress, timings, solver)
    with timings.stage("assembly"):
        progress("air mesh follows the membrane (ALE) ...")
        motion = meridian_motion(state, state.mesh, air["domain_radius"])
        progress("assembling the air of every order ...")
        meridian_air = MeridianAir(state, study, motion)
    initial_shifts = initial_shifts or {}
    forms = OrderForms(state, study)
    modes, pressures, dry, partners, results, operators = [], [], [], {}, {}, []
    for m in range(MAX_ORDER + 1):
        def say(text, m=m):
            progress(f"m = {m}: {text}")
        with timings.stage("eigen"):
            dry_operators, dry_result = _dry_order(study, forms, m, 1.5 * eigen["f_max"], say)
        with timings.stage("assembly"):
            coupled = coupled_order_operators(state, study, dry_operators, meridian_air)
        expected = int(np.count_nonzero(dry_result.freq_hz <= 1.1 * eigen["f_max"])) + 2
        with timings.stage("eigen"):
            say(f"coupled modes ({coupled.stiffness.shape[0]} unknowns) ...")
            damping = forms.damping(dry_operators)
            result = solve_structural_band(
                                coupled.stiffness, coupled.mass, eigen["f_min"], eigen["f_max"],
                                None if damping is None else damping.embedded(
                                    coupled.membrane_index, coupled.stiffness.shape[0]),
                                factorize=coupled.factorize, start_modes=expected,
                                max_imag_hz=eigen["max_damping_ratio"] * eigen["f_max"],
                                initial_shifts=initial_shifts.get(f"m={m}"), progress=say,
                                **_band(study, hermitian=False))
        with timings.stage("classify"):
            sampler = OrderSampler(state, dry_operators.space, dry_operators.axis_m1)
            order_dry = classify_order(dry_operators, dry_result.vectors, dry_result.freq_hz,
                                       dry_result.freq_im_hz, dry_result.residuals, sampler)
            number_out_of_plane(order_dry)
            membrane = result.vectors[coupled.membrane_index]
            order_modes = classify_order(dry_operators, membrane, result.freq_hz,
                                         result.freq_im_hz, result.residuals, sampler)
            full = dry_operators.to_full(membrane)
            order_pressures = []
            for k, (mode, fraction) in enumerate(zip(order_modes, membrane_energy_fractions(
                    coupled, result))):
                mode.membrane_energy_fraction = fraction
                if fraction < air["min_membrane_energy"]:
                    mode.kind = AIR
                scale = np.linalg.norm(mode.vector) / max(np.linalg.norm(full[:, k]), 1e-300)
                order_pressures.append(result.vectors[coupled.pressure_index, k]
                                       * coupled.pressure_scale * scale)
            number_out_of_plane(order_modes)
            order_partners = match_dry(order_modes, order_dry, dry_operators.mass_full,
                                       same_order_family)
        structural = [mode for mode in order_modes if mode.kind != AIR]
        if not structural and not np.any(dry_result.freq_hz <= 1.5 * eigen["f_max"]):
            break
        results[f"m={m}"] = result
        operators.append(coupled)
        for k, mode in enumerate(order_modes):
            twins = with_pairs([mode])
            for twin in twins:
                if k in order_partners:
                    partners[id(twin)] = order_partners[k]
                modes.append(twin)
                pressures.append(order_pressures[k])
        dry += with_pairs(order_dry)
    order = sorted(range(len(modes)), key=lambda k: (modes[k].freq_hz, modes[k].m,
                                                     modes[k].family))
    modes, pressures = [modes[k] for k in order], [pressures[k] for k in order]
    for index, mode in enumerate(modes):
        mode.index = index
    label_all(modes)
    dry.sort(key=lambda mode: (mode.freq_hz, mode.m, mode.family))
    label_all(dry)
    partner_hz = {index: partners[id(mode)].freq_hz for index, mode in enumerate(modes)
                  if id(mode) in partners}
    return CoupledSolution(state, modes, pressures, dry, partner_hz, SectorBandResults(results),
                           operators)
