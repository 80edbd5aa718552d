"""The axisymmetric engine's stages: meridian mesh -> prestress -> orders m -> modes.

Orders are solved m = 0, 1, 2, ... from 0 Hz up (:mod:`copdea_fem.fe.bands`): each
order's dry band is solved from 0 Hz, so the radial order n of an out-of-plane
mode is its rank among all the out-of-plane modes of its order, whatever the
band asked (the modes below ``f_min`` are dropped after numbering).  The loop
stops by :class:`copdea_fem.fe.bands.OrderStop`: at the first order whose lowest
mode lies above the top of the band and above the lowest mode of the order
before (the lowest frequency of an order rises with m, checked; the higher
modes of an order do not, so an order with nothing in the band does not stop
it).  Coupled: the dry partner band reaches 1.5 f_max, an order whose lowest
dry mode lies above it holds no structural mode in the band (an added mass
above 125 % of a modal mass would be needed) and is not solved coupled; the
n of a coupled out-of-plane mode is its dry partner's (best MAC).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import logging

import numpy as np

from copdea_fem.fe.axisymmetric.air import meridian_motion
from copdea_fem.fe.axisymmetric.meridian import MeridianSpec, meridian_mesh
from copdea_fem.fe.axisymmetric.modes import (
    CavitySampler,
    OrderSampler,
    classify_order,
    coupled_order_modes,
    label_all,
    name_coupled_order,
    number_out_of_plane,
    numbered_dry_modes,
    sampled_shapes,
    with_pairs,
)
from copdea_fem.fe.axisymmetric.operators import (
    MeridianAir,
    OrderForms,
    coupled_order_operators,
    dry_order,
)
from copdea_fem.fe.axisymmetric.perturbation import perturbed_coupled_modes, perturbed_modes
from copdea_fem.fe.axisymmetric.prestress import make_axisymmetric_solver
from copdea_fem.fe.bands import BandSolver, OrderStop, coupled_start_modes
from copdea_fem.fe.cavity import (
    lowest_order_frequency,
    without_static_solution,
)
from copdea_fem.fe.eigen import SectorBandResults
from copdea_fem.fe.forced.problem import DrivenPart, band_parts
from copdea_fem.fe.modes import match_dry
from copdea_fem.fe.solution import CoupledSolution
from copdea_fem.progress import Timings, single_threaded_blas, tagging
from copdea_fem.study import StudyError
from copdea_fem.study.imperfections import imperfection_keys_given

#: Highest order tried before giving up (a band this rich is a mistake in the study).
MAX_ORDER = 400


logger = logging.getLogger(__name__)


def prepare_meridian(study):
    """The meridian mesh of the study (not cached: Netgen meshes it quickly)."""
    return meridian_mesh(MeridianSpec.from_study(study), study.mesh.curve_order)


def solve_axisymmetric_prestress(study, mesh, solver=None):
    from copdea_fem.fe.prestress import solve_prestress
    solver = solver or make_axisymmetric_solver(study, mesh)
    return solve_prestress(study, mesh, solver=solver)


def _prestressed(study, mesh, timings, solver):
    """The mesh and prestress stages (the mesh made unless given)."""
    if mesh is None:
        with timings.stage("mesh"):
            mesh = prepare_meridian(study)
    with timings.stage("prestress"):
        logger.info("prestress (axisymmetric Newton, load steps in z then V_b) ...")
        return solve_axisymmetric_prestress(study, mesh, solver)


def order_sampler(samplers: dict, state, operators) -> OrderSampler:
    """The :class:`.modes.OrderSampler` of ``operators``' space, made once per space in
    ``samplers`` (the orders m >= 1 share a space, :class:`.operators.OrderForms`)."""
    space = operators.space
    if id(space) not in samplers:       # the sampler holds the space: its id stays unique
        samplers[id(space)] = OrderSampler(state, space, operators.axis_m1)
    return samplers[id(space)]


def _in_band(modes, f_min, f_max):
    return [mode for mode in modes if f_min <= mode.freq_hz <= f_max]


def axisymmetric_dry_modes(study, mesh=None, timings=None, solver=None,
                           initial_shifts=None, band: BandSolver | None = None):
    """Prestress and dry modes in the band, order by order: (state, modes, results)."""
    timings = timings or Timings()
    band = band or BandSolver.from_study(study)
    state = _prestressed(study, mesh, timings, solver)
    modes, results = [], {}
    initial_shifts = initial_shifts or {}
    forms = OrderForms(state, study)
    samplers = {}                  # one per order space (the orders m >= 1 share theirs)
    stop = OrderStop(band.f_max)
    for m in range(MAX_ORDER + 1):
        with timings.stage("eigen"), tagging(f"m = {m}: "):
            operators, result, lowest = dry_order(band, forms, m, band.f_max,
                                                   initial_shifts.get(f"m={m}"))
        stop.record(lowest)
        if stop.done():
            break
        if len(result) == 0:
            continue
        results[f"m={m}"] = result
        with timings.stage("classify"):
            order_modes = classify_order(operators, result.vectors, result.freq_hz,
                                         result.freq_im_hz, result.residuals,
                                         order_sampler(samplers, state, operators))
            number_out_of_plane(order_modes)
            modes += with_pairs(_in_band(order_modes, band.f_min, band.f_max))
    if imperfection_keys_given(study.membrane, study.imperfections):
        with timings.stage("perturbation"):
            modes = perturbed_modes(state, modes, study, forms)
    modes.sort(key=lambda mode: (mode.freq_hz, mode.m, mode.family))
    for index, mode in enumerate(modes):
        mode.index = index
    label_all(modes)
    return state, modes, SectorBandResults(results)


def refuse_imperfect(study, what: str) -> None:
    """Refuse (StudyError) ``what`` for an imperfect device: the perturbation path
    (:mod:`.perturbation`) makes modes only (dry and coupled)."""
    imperfect = imperfection_keys_given(study.membrane, study.imperfections)
    if imperfect:
        raise StudyError(
            f"mesh.engine = 'axisymmetric' is not allowed for {what} with {imperfect} (its "
            "first-order perturbation path makes modes only (dry and coupled): "
            "frequencies, labels, orientations, turned shapes); allowed: mesh.engine: 3d "
            "(or auto)")


def same_order_family(mode, dry) -> bool:
    """Pairing rule within one order: same kind and (out-of-plane) the same n."""
    return dry.kind == mode.kind and (mode.kind == "in-plane" or dry.n == mode.n)


def axisymmetric_coupled_modes(study, mesh=None, timings=None, solver=None,
                               initial_shifts=None, band: BandSolver | None = None):
    """Prestress, dry partners and fully-coupled membrane-air modes, order by order.

    Returns a :class:`copdea_fem.fe.solution.CoupledSolution` (``operators``: the
    coupled pencil of each order, in order).
    """
    timings = timings or Timings()
    band = band or BandSolver.from_study(study)
    air = study.air
    state = _prestressed(study, mesh, timings, solver)
    with timings.stage("assembly"):
        logger.info("air mesh follows the membrane (ALE) ...")
        cavity = MeridianSpec.from_study(study).cavity        # None: an open back
        motion = meridian_motion(state, state.mesh, air.domain_radius, cavity=cavity)
        logger.info("assembling the air of every order ...")
        meridian_air = MeridianAir(state, study, motion)
    initial_shifts = initial_shifts or {}
    forms = OrderForms(state, study)
    modes, pressures, dry, partners, results, operators = [], [], [], {}, {}, []
    samplers = {}                  # one per order space (the orders m >= 1 share theirs)
    stop = OrderStop(band.dry_partner_top)
    cavity_sampler = None if cavity is None else CavitySampler(meridian_air.pressure_space,
                                                               cavity)
    for m in range(MAX_ORDER + 1):
        def say(text, m=m):
            logger.info(f"m = {m}: {text}")
        with timings.stage("eigen"), tagging(f"m = {m}: "):
            dry_operators, dry_result, lowest = dry_order(band, forms, m,
                                                           band.dry_partner_top)
        if cavity is not None:     # the enclosure's own modes of order m start here too
            lowest = min(lowest, lowest_order_frequency(m, cavity.radius, air.sound_speed))
        stop.record(lowest)
        if stop.done():
            break
        if stop.above():      # no dry partner below 1.5 f_max: no structural mode in the band
            continue
        with timings.stage("assembly"):
            coupled = coupled_order_operators(state, study, dry_operators, meridian_air)
        expected = coupled_start_modes(dry_result.freq_hz, band.f_min, band.f_max)
        with timings.stage("eigen"), tagging(f"m = {m}: "):
            say(f"coupled modes ({coupled.stiffness.shape[0]} unknowns) ...")
            damping = forms.damping(dry_operators)
            result = band.solve(coupled.stiffness, coupled.mass, band.f_min, band.f_max,
                                hermitian=False, factorize=coupled.factorize,
                                damping=None if damping is None else damping.embedded(
                                    coupled.membrane_index, coupled.stiffness.shape[0]),
                                start_modes=expected, max_imag_hz=band.max_imag_hz,
                                initial_shifts=initial_shifts.get(f"m={m}"))
        if cavity is not None:
            result = without_static_solution(result, band.f_max)
        with timings.stage("classify"):
            sampler = order_sampler(samplers, state, dry_operators)
            order_dry = numbered_dry_modes(dry_operators, dry_result, sampler)
            order_modes, order_pressures = coupled_order_modes(
                coupled, result, air.min_membrane_energy, sampler)
            name_coupled_order(order_modes, order_pressures, order_dry, coupled, cavity_sampler)
            order_partners = match_dry(order_modes, order_dry, dry_operators.mass_full,
                                       same_order_family)
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
    if imperfection_keys_given(study.membrane, study.imperfections):
        with timings.stage("perturbation"):
            modes, dry, partners = _perturbed_coupled(state, modes, pressures, operators, dry,
                                                      partners, study, forms)
    order = sorted(range(len(modes)), key=lambda k: (modes[k].freq_hz, modes[k].m,
                                                     modes[k].family))
    modes, pressures = [modes[k] for k in order], [pressures[k] for k in order]
    for index, mode in enumerate(modes):
        mode.index = index
    label_all(modes)
    dry.sort(key=lambda mode: (mode.freq_hz, mode.m, mode.family))
    label_all(dry)
    # the dry partner band as the 3-D engine's: f_min .. 1.5 f_max (below f_min it only
    # numbered the modes); a wet mode's partner lies above it, so none is dropped
    dry = [mode for mode in dry if mode.freq_hz >= band.f_min]
    partner_hz = {index: partners[id(mode)].freq_hz for index, mode in enumerate(modes)
                  if id(mode) in partners}
    def order_pencil(m: int):
        """The coupled operators of order m (one the loop did not solve: the static
        correction of a drive's orders above the band)."""
        return coupled_order_operators(state, study, forms.operators(m), meridian_air)

    return CoupledSolution(state, modes, pressures, dry, partner_hz, SectorBandResults(results),
                           operators, order_pencil, forms.operators)


def _perturbed_coupled(state, modes, pressures, pencils, dry, partners, study, forms):
    """An imperfect device's coupled modes and dry partners (:mod:`.perturbation`): (modes,
    dry modes, partners {id(mode): its dry partner}), both lists in their places; a
    member's partner is the perturbed dry mode in its partner's place (a pair's sin member:
    the place after its cos member's, :func:`.modes.with_pairs`)."""
    place = {id(mode): k for k, mode in enumerate(dry)}
    partner_place = {}
    for k, mode in enumerate(modes):
        partner = partners.get(id(mode))
        if partner is not None:
            partner_place[k] = place[id(partner)] + (1 if mode.family == "sin"
                                                     and partner.m > 0 else 0)
    modes = perturbed_coupled_modes(state, modes, pressures, {p.m: p for p in pencils},
                                    study, forms)
    dry = perturbed_modes(state, dry, study, forms)
    return modes, dry, {id(modes[k]): dry[j] for k, j in partner_place.items()}


#: The highest order m whose static response a drive of many orders (a segment's indicator,
#: eq. 4 of :mod:`copdea_fem.fe.forced.electrode`) gets beyond the solved orders.  The
#: indicator's orders fall as ``|c_m + i s_m| <= 2 / (pi m)``.  Out of the plane an order's
#: static response to a weight of order m falls as ``r^2 / (T m^2)`` (the hoop term
#: ``T m^2 / r^2`` of the membrane's stiffness), so the orders above M add ~``1 / M^2``:
#: measured on the quick G1 (a 90- and a 45-degree segment, Q1-Q3 at 9 angles), the axial
#: velocity of the orders above 60 is 1e-4 of the largest.  In the plane the co-energy's
#: weight puts a line force along the segment's edges, whose order-m part does not fall
#: with m: the orders above M add ~``1 / M`` of the in-plane velocity (measured: 3 % above
#: 60, 1 % above 120, against 240).  The motional current (``statespace``) converges as
#: ``1 / M`` too: the edges' line force both drives and senses, ``F_m^T K_m^-1 F_m`` of an
#: order does not fall with m and its two coefficients give ``1 / m^2``.  No truncation below
#: this order holds the outputs to 1e-4: measured on the quick G1 with three segments (an
#: inner ring, the outer ring in two halves; Q1-Q3 at 0 and 30 degrees), relative to the
#: model's static response at the outputs (omega -> 0), the orders 62-120 add 5e-5 of the
#: axial displacement, 7e-4 of the in-plane one and 3e-3 of the currents; the orders 42-120
#: 2e-4, 2e-4 and 6e-3.  With a segment's edge through the points (MIXED of the tests) the
#: in-plane share of the orders 62-120 is 2.4e-2.
STATIC_ORDERS = 120


class LazyPencil:
    """An order's pencil built at first use (the static orders of
    :meth:`AxisymmetricEngine.driven_parts`: only those a weight drives are built)."""

    def __init__(self, build):
        self.build, self.pencil = build, None

    def __getattr__(self, name):
        if name in ("build", "pencil"):
            raise AttributeError(name)
        if self.pencil is None:
            self.pencil = self.build()
        return getattr(self.pencil, name)


class EmptyBand:
    """The band result of an order without a mode in the band: no eigenvalue, no vector
    (its pencil's unknowns by none)."""

    def __init__(self, pencil):
        self.pencil = pencil
        self.eigenvalues = np.zeros(0, dtype=complex)

    @property
    def vectors(self) -> np.ndarray:
        return np.zeros((self.pencil.stiffness.shape[0], 0), dtype=complex)


def static_orders(order_pencil, solved, highest: int = STATIC_ORDERS) -> list[DrivenPart]:
    """The parts of the orders ``0 .. highest`` not in ``solved``, each with an empty band
    and its pencil ``order_pencil(m)`` built at first use."""
    parts = []
    for m in range(highest + 1):
        if m in solved:
            continue
        pencil = LazyPencil(lambda m=m: order_pencil(m))
        parts.append(DrivenPart(f"m={m}", pencil, EmptyBand(pencil), m=m))
    return parts


class AxisymmetricEngine:
    """The axisymmetric engine (``mesh.engine: axisymmetric``) behind
    :class:`copdea_fem.fe.engines.Engine`: a meridian (r, z) mesh, one 2-D problem per order m."""

    name = "axisymmetric"

    def __init__(self):
        # id(prestressed state) -> (weak reference to it, its WeightForcings): the forcings
        # of electrode_forcing, kept while the state lives
        self.forcings: dict = {}

    def mesh_key(self, study, with_air: bool):
        """What the meridian mesh depends on (it always holds the air)."""
        return MeridianSpec.from_study(study), study.mesh.curve_order

    def space_key(self, study, with_air: bool) -> str:
        """The FE space of the modes' vectors: the meridian mesh's spec (it always holds the
        air), order and curving."""
        spec = json.dumps(dataclasses.asdict(MeridianSpec.from_study(study)), sort_keys=True,
                          default=str)
        digest = hashlib.sha1(spec.encode()).hexdigest()[:16]
        return (f"axisymmetric:{digest}:order{study.mesh.order}:"
                f"curve{study.mesh.curve_order}")

    def prepare_mesh(self, study, with_air=None, cache_dir=None):
        return prepare_meridian(study)

    def prestress_solver(self, study, mesh):
        return make_axisymmetric_solver(study, mesh)

    def dry_modes(self, study, mesh, timings=None, solver=None,
                  initial_shifts=None, band=None):
        with single_threaded_blas():   # 2-D problems: NGSolve's TaskManager only costs here
            return axisymmetric_dry_modes(study, mesh, timings, solver,
                                          initial_shifts, band)

    def coupled_modes(self, study, mesh, timings=None, solver=None,
                      initial_shifts=None, band=None):
        with single_threaded_blas():
            return axisymmetric_coupled_modes(study, mesh, timings, solver,
                                              initial_shifts, band)

    def threads(self):
        """The threading context of the output and force stages: none (2-D problems)."""
        return contextlib.nullcontext()

    def estimate_size(self, study):
        """(elements, unknowns) of the meridian mesh (:func:`.meridian.estimate_size`)."""
        from copdea_fem.fe.axisymmetric.meridian import estimate_size
        mesh = study.mesh
        return estimate_size(MeridianSpec.from_study(study), mesh.order,
                             mesh.pressure_order)

    def forced_problem(self, study):
        """Meridian mesh, prestress and the forced order m = 0
        (:mod:`copdea_fem.fe.axisymmetric.forced`)."""
        import time

        from copdea_fem.fe.axisymmetric.forced import order_zero_problem
        refuse_imperfect(study, "a forced response")
        timings = {}
        start = time.perf_counter()
        mesh = prepare_meridian(study)
        logger.info("prestress (axisymmetric Newton, load steps in z then V_b) ...")
        state = solve_axisymmetric_prestress(study, mesh)
        timings["prestress"] = time.perf_counter() - start
        return order_zero_problem(study, mesh, state, timings)

    def driven_sector(self):
        """The order m = 0 (:data:`copdea_fem.fe.axisymmetric.forced.MERIDIAN_SECTOR`)."""
        from copdea_fem.fe.axisymmetric.forced import MERIDIAN_SECTOR
        return MERIDIAN_SECTOR

    def driven_parts(self, solution, study) -> list[DrivenPart]:
        """The orders m of a solve with their pencils: the coupled operators the solve kept
        (with air), else each order's dry operators rebuilt; then every order up to
        :data:`STATIC_ORDERS` that the solve holds no mode of, with an empty band: what a
        weight of many Fourier orders (a segment) drives there is the static correction of
        its modes, all above the band (:func:`static_orders`).

        The static orders get the membrane's own pencil (a
        :class:`copdea_fem.fe.forced.harmonic.DryPencil`), with or without the air: the
        coupled ``A = [[K_s, C^T], [0, K_a]]`` is block triangular (harmonic module notes),
        so its static solve ``A^-1 (f, 0) = (K_s^-1 f, 0)`` - the correction's r0 - is the
        membrane's, exactly (the air has no static load: measured 1e-12 on the quick G1).
        The air enters ``r1 = A^-1 B A^-1 F`` alone, by its added mass on the membrane:
        left out there, r1 changes by 7e-3 at m = 11, 7e-4 at m = 31, 4e-5 at m = 91 (quick
        G1), and r1's share of the correction in the band, ``omega^2 r1 ~ (f / f_m)^2 r0``
        with f_m above 1.5 f_max, is below a quarter of that."""
        from copdea_fem.fe.forced.harmonic import DryPencil

        refuse_imperfect(study, "a forced response")
        bands = band_parts(solution.eigen)
        forms = OrderForms(solution.state, study)
        if solution.coupled is not None:
            pencils = list(solution.coupled.operators)
            order_pencil = getattr(solution.coupled, "order_pencil", None)
        else:
            pencils = [DryPencil(forms.operators(int(key.split("=")[1]))) for key in bands]

            def order_pencil(m):
                return DryPencil(forms.operators(m))
        parts = [DrivenPart(key, pencil, band, m=int(pencil.membrane.m))
                 for (key, band), pencil in zip(bands.items(), pencils)]
        if order_pencil is None:        # a coupled solution made without its air: none
            return parts
        solved = {part.m for part in parts}
        # the solve's forms where it kept them (their Hessians are assembled already)
        operators = getattr(solution.coupled, "order_operators", None) or forms.operators
        return parts + static_orders(lambda m: DryPencil(operators(m)), solved, STATIC_ORDERS)

    def electrode_forcing(self, state, part: DrivenPart, electrode) -> np.ndarray:
        """The forcing [N/V] of the weight ``rho(R) cos(m theta)`` on the order's cos family,
        ``rho`` the weight's radial factor
        (:func:`copdea_fem.fe.axisymmetric.forcing.order_forcing`; ``electrode``'s factors of
        the order's families: :meth:`copdea_fem.fe.forced.problem.DrivenPart.families`)."""
        from copdea_fem.fe.axisymmetric.forcing import WeightForcings
        import weakref
        held = self.forcings.get(id(state))
        if held is None or held[0]() is not state:
            self.forcings = {key: value for key, value in self.forcings.items()
                             if value[0]() is not None}
            held = self.forcings[id(state)] = (weakref.ref(state), WeightForcings(state))
        return held[1](part.pencil.membrane, electrode)

    def point_sampler(self, state, positions):
        """The fields of ``state`` at points of the prestressed device
        (:class:`copdea_fem.fe.axisymmetric.points.MeridianPoints`)."""
        from copdea_fem.fe.axisymmetric.points import MeridianPoints
        return MeridianPoints(state, positions)

    def prestressed_positions(self, state, reference_xy, disc_z: float) -> np.ndarray:
        """Where reference points lie on the prestressed device
        (:meth:`copdea_fem.fe.points.PointSampler.prestressed_positions`)."""
        from copdea_fem.fe.axisymmetric.points import MeridianPoints
        return MeridianPoints.prestressed_positions(state, reference_xy, disc_z)

    def tracking_arrays(self, state, modes, needs_sampling: bool) -> dict:
        """Orders have spaces of their own: the sweeps compare shapes on the polar grid
        (:func:`.modes.sampled_shapes`)."""
        return {"sampled": sampled_shapes(state, modes)}

    def output(self, state, modes=()):
        """The result fields of ``state`` revolved to 3-D for ParaView and the API
        (:class:`copdea_fem.fe.axisymmetric.fields.RevolvedOutput`; ``modes``: those written
        together, their highest order sets the angles)."""
        from copdea_fem.fe.axisymmetric.fields import RevolvedOutput
        return RevolvedOutput(state, modes)
