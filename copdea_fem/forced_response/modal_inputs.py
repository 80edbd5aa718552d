r"""The band's coupled modes driven by several inputs: the modal model that ``excite`` and
``statespace`` share.

Inputs
------
An input is ``(name, weight)``: a drive weight on the electrostatic co-energy (an
:class:`copdea_fem.fe.forced.electrode.ElectrodeImperfection`, or any object with its
``family_weights(m)`` and ``weight``/``sector_weight``: a segment's indicator), driven by its
own AC voltage ``V~_k`` on top of the common bias ``load.voltage``.  The uniform electrode is
``("electrode", ElectrodeImperfection())``.  Each driven part of the solve
(:meth:`copdea_fem.fe.engines.Engine.driven_parts`: an order m with its cos and sin families,
or a 3-D symmetry sector) is a *channel*; input k forces a channel with
``F_k = factor_k f_k`` [N/V] (:meth:`copdea_fem.fe.engines.Engine.electrode_forcing`, the
factor from :meth:`copdea_fem.fe.forced.problem.DrivenPart.families`).

Modal model (the modal path of :mod:`copdea_fem.fe.forced.harmonic`)
-------------------------------------------------------------------
Per channel and band column j (right vector ``x_j``, left ``y_j``, ``n_j = y_j^T B x_j``)
the response per volt of input k is, in the FE's ``e^{-i omega t}`` convention,

    c_jk(omega) = p_jk / d_j(omega),   p_jk = y_j^T F_k,
    d_j(omega) = n_j (lambda_j - omega^2) - i omega lambda_j (b/m)_j m_j          (1)

with the paper's modal damping (b/m)_j by label (``reduced.damping_*``, eq. 19; air and PML
columns none) and ``m_j = u_j^T M_s u_j``; the modes above the band enter through the
static correction ``r0_k + omega^2 r1_k`` (harmonic module notes).

Pressure at the microphones
---------------------------
The sound at a microphone (``response.microphones``, :func:`.run.parse_microphones`) is that
of the part a uniform electrode drives (the order m = 0, the even-even sector:
:attr:`copdea_fem.fe.forced.problem.DrivenPart.uniform`), as ``response`` computes it
(:class:`.observers.Microphones`).  That part's band is then ``response``'s modal path's
(:func:`radiating_band`: ``Re f`` and ``|Im f|`` up to ``response.modal_band`` times
``eigen.f_max``): the strongly damped air and PML modes, which ``solve``'s band leaves out,
carry the sound as much as the structural ones.

- A microphone inside the Kirchhoff sphere reads the FE's own pressure at its point, a
  constant linear gain on each column: the model is exact there (measured on the quick G1
  in a baffle: 2e-4 of the peak against ``response``'s modal path; the state space, with
  its conjugate poles and pseudo-modes, 0.3-0.7 %).
- Beyond it, the Kirchhoff-Helmholtz integral's kernels depend on the frequency.  With the
  propagation delay ``|x_m| / c`` taken out, column j's pressure at the microphone,
  ``P_mj(omega) = e^{-i k |x_m|} p_m(x_j; k)`` (``k = omega / c``; ``e^{+i k R}`` is the
  outgoing wave of the FE's ``e^{-i omega t}``), varies smoothly over the band (the phase
  ``k r.y`` across the sphere and the ``ik - 1/R`` of dG/dn); the model holds it to first
  order in the time derivative,

      P_mj(omega) ~ P_mj + (-i omega) P'_mj,                                          (3)

  fitted in least squares on :data:`KERNEL_FIT_LINES` lines up to ``eigen.f_max`` and the
  column's own frequency ``|Re sqrt(lambda_j)|`` (when in the band), each line weighted by
  the column's modal response ``1 / |d_j(omega)|`` (1): the fit is best where the column
  sounds, exact at a lightly damped mode's peak.  The static correction's ``r0_k`` and
  ``r1_k`` are fitted with equal weights.  A pressure that is a constant gain plus one on
  the rate is a proper LTI output (``statespace``: ``s z`` is a state's derivative, the
  rest a feedthrough), a second-order term would not be.  The model's pressure is the
  microphone's advanced by ``|x_m| / c`` (a pure delay, left to the user).  Measured on the
  quick G1 in a baffle at 1 m on the axis, 100-900 Hz, against ``response``'s modal path:
  the kernels exact on every line 2e-4 of the peak pressure; (3) 1.5 %; one constant kernel
  per column at its own frequency 21 % (the state space 4.8 % and 16 %).

The orders m >= 1 (the other sectors) radiate nothing onto the axis; off it, ``statespace``
refuses microphones with segments as ``response`` does.

Self-sensing current
--------------------
The charge of input k's electrode is ``Q_k = C_k(u) V`` with ``C_k`` the weighted
capacitance, so at the bias ``i_k = C_k0 dV_k/dt + V_b dC_k/du . du/dt``.  The forcing is
``f_k = V_b dC_k/du`` (harmonic module notes: ``f = V_b dC/du``), hence the motional current

    i_k = F_k^T v    [A],   v = du/dt,                                              (2)

the same vector that forces the membrane (electromechanical reciprocity, factor 1 in SI:
the velocity per volt of input l seen by input k's current is the velocity per volt of
input k seen by input l's current).  The blocked term ``C_k0 dV_k/dt`` is a pure
differentiator of the input: not a proper LTI output, it is left out of the model and
``C_k0`` is not computed here (``statespace`` says so in its units).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

logger = logging.getLogger(__name__)

#: The kind of an out-of-plane mode (:mod:`copdea_fem.fe.modes`).
OUT_OF_PLANE = "out-of-plane"

#: The quarter points Q1-Q3 (fractions of the width from the inner edge, Sect. 5.3) are
#: observed at these angles [deg]: 0 (the cos families' maximum) and 30 (where the sin
#: families of the orders 1-5 are not on a nodal line).
POINT_ANGLES_DEG = (0.0, 30.0)


def drive_inputs(study) -> list[tuple[str, object]]:
    """The study's inputs ``(name, weight)``: its segments (``electrodes.segments``,
    :func:`copdea_fem.fe.forced.electrode.segment_weights`; without segments the whole
    electrode, one AC voltage on the whole membrane).  The segments' ``drive`` is not
    applied: each segment is an input of its own."""
    from copdea_fem.fe.forced.electrode import segment_weights
    return [(name, weight) for name, weight, _ in segment_weights(study)]


def study_points(solution, study) -> tuple[list[str], np.ndarray]:
    """Names and positions (P, 3) [m] on the prestressed device of the observed points: Q1-Q3
    (:data:`copdea_fem.study.schema.QUARTER_POINTS`) at each angle of
    :data:`POINT_ANGLES_DEG`; names ``q<i>_<angle>deg``."""
    from copdea_fem.study.schema import QUARTER_POINTS
    state = solution.state
    r_i, r_o = float(state.inner_radius), float(state.outer_radius)
    names, reference = [], []
    for angle in POINT_ANGLES_DEG:
        for index, fraction in enumerate(QUARTER_POINTS, start=1):
            radius = r_i + fraction * (r_o - r_i)
            theta = np.radians(angle)
            names.append(f"q{index}_{angle:g}deg")
            reference.append((radius * np.cos(theta), radius * np.sin(theta)))
    positions = solution.engine.prestressed_positions(state, np.array(reference),
                                                      study.load.z)
    return names, positions


@dataclass
class Channel:
    """One driven field (a part's family) with its band columns and what the inputs do to it.

    Attributes
    ----------
    name : str
        ``<part key>:<family>``.
    labels : list of str
        Each column's label (``""``: an air/PML or unlabelled column).
    structural : (J,) bool array
        Columns of labelled structural modes.
    out_of_plane : (J,) bool array
        Columns of labelled out-of-plane modes (what a vibrometer and the sound see).
    eigenvalues : (J,) complex array
        lambda_j [rad^2/s^2].
    norms : (J,) complex array
        n_j of (1).
    damping : (J,) complex array
        ``lambda_j (b/m)_j m_j`` of (1).
    participation : (J, K) complex array
        p_jk of (1) [per volt of input k].
    displacement : (P, 3, J) complex array
        Each column's displacement at the points (peak |u| = 1 normalisation of the band).
    currents : (K, J) complex array
        ``F_k^T u_j`` of (2): input k's motional current per unit velocity of column j.
    residual_displacement : (P, 3, K) complex array
        r0_k at the points [m/V].
    residual_displacement1 : (P, 3, K) complex array
        r1_k at the points [m s^2/V].
    residual_currents : (K, K) complex array
        ``F_l^T r0_k`` [C/V per ... : A s/V] (row l, column k).
    residual_currents1 : (K, K) complex array
        ``F_l^T r1_k``.
    pressure : (M, J) complex array
        P_mj of (3) [Pa per unit of column j] at the model's microphones (zero where the
        channel does not radiate: module notes).
    pressure_rate : (M, J) complex array
        P'_mj of (3) [Pa s per unit of column j].
    residual_pressure, residual_pressure_rate : (M, K) complex arrays
        The pressure (3) of r0_k [Pa/V] and its rate [Pa s/V].
    residual_pressure1, residual_pressure1_rate : (M, K) complex arrays
        The pressure (3) of r1_k [Pa s^2/V] and its rate [Pa s^3/V].
    """

    name: str
    labels: list
    structural: np.ndarray
    out_of_plane: np.ndarray
    eigenvalues: np.ndarray
    norms: np.ndarray
    damping: np.ndarray
    participation: np.ndarray
    displacement: np.ndarray
    currents: np.ndarray
    residual_displacement: np.ndarray
    residual_displacement1: np.ndarray
    residual_currents: np.ndarray
    residual_currents1: np.ndarray
    pressure: np.ndarray
    pressure_rate: np.ndarray
    residual_pressure: np.ndarray
    residual_pressure_rate: np.ndarray
    residual_pressure1: np.ndarray
    residual_pressure1_rate: np.ndarray

    def denominators(self, omega) -> np.ndarray:
        """d_j(omega) of (1), (F, J), FE convention."""
        return denominators(self.eigenvalues, self.norms, self.damping, omega)

    def pressure_kernels(self, omega) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pressure (3) at ``omega`` [rad/s] (F,): of the columns (F, M, J), of r0_k and
        of r1_k (F, M, K); FE convention."""
        rate = -1j * np.asarray(omega, float)[:, None, None]
        return (self.pressure + rate * self.pressure_rate,
                self.residual_pressure + rate * self.residual_pressure_rate,
                self.residual_pressure1 + rate * self.residual_pressure1_rate)


@dataclass
class ModalInputs:
    """The modal model (module notes) of a solve driven by inputs, observed at points.

    Attributes
    ----------
    inputs : list of str
        The inputs' names (K).
    point_names : list of str
        The points' names (P).
    positions : (P, 3) array
        Where they are [m].
    channels : list of Channel
    microphones : list of (str, (3,) array)
        The microphones' names and positions [m] (M; none without the outside air).
    microphone_delays : list of float
        ``|x_m| / c`` [s] of each: what the model's pressure is advanced by (eq. 3).
    """

    inputs: list
    point_names: list
    positions: np.ndarray
    channels: list = field(default_factory=list)
    microphones: list = field(default_factory=list)
    microphone_delays: list = field(default_factory=list)

    @classmethod
    def build(cls, solution, study, inputs, positions, point_names,
              microphones=(), radiating: bool = False) -> ModalInputs:
        """The model of ``solution`` (a :class:`copdea_fem.fe.SolveResult` of ``study``) for
        ``inputs`` (``[(name, weight), ...]``) at ``positions`` (P, 3) [m] and
        ``microphones`` (``[(name, (x, y, z) [m]), ...]``, :func:`.run.parse_microphones`;
        the solve must hold the outside air).  With microphones, or ``radiating``, the part
        a uniform electrode drives takes :func:`radiating_band` (with the air): its air and
        PML modes become columns, not part of the static correction (``statespace`` asks
        for it: :mod:`.state_space`, "Static correction")."""
        import scipy.sparse as sp

        from copdea_fem.fe.forced.harmonic import ForcedOrder, ModalBasis
        from copdea_fem.forced_response.observers import ScanPoints
        from copdea_fem.forced_response.run import modal_damping
        from copdea_fem.forced_response.scan import part_modes

        engine, state = solution.engine, solution.state
        model = cls([name for name, _ in inputs], list(point_names),
                    np.asarray(positions, float), microphones=list(microphones),
                    microphone_delays=microphone_delays(study, microphones))
        points = ScanPoints(engine.point_sampler(state, positions), 1)
        for part in engine.driven_parts(solution, study):
            if ((microphones or radiating) and part.uniform
                    and len(part.pencil.pressure_index)):
                part = radiating_band(part, study)
            band = part.band
            drives = [driven_families(part, weight) for _, weight in inputs]
            if len(band.eigenvalues) == 0 and not any(drives):
                continue            # no mode, no input drives it (its pencil is not built)
            size = part.pencil.membrane.stiffness.shape[0]
            zero = sp.csr_matrix((size, size))
            columns = part_modes(part, solution.modes)
            labels = [columns[k][0].label if k in columns else ""
                      for k in range(len(band.eigenvalues))]
            kinds = [columns[k][0].kind if k in columns else "air"
                     for k in range(len(band.eigenvalues))]
            damping_per_mass = modal_damping(labels, kinds, study)
            # one basis per distinct forcing: the axisymmetric engine forces an order by one
            # vector per radial factor of the weights (the inputs differ by their families'
            # factors), the 3-D engine by each input's folded weight, the same up to a sign
            # for a mirrored segment (mirrored_inputs); an input that does not drive the part
            # needs none (None), and all of a part's share one factorisation
            mirrors = mirrored_inputs(inputs, part.sector) if part.m is None else {}
            factors, keys = {}, []
            for k, driven in enumerate(drives):
                source, sign = mirrors.get(k, (k, 1.0))
                for family, factor in driven:
                    factors[(family, k)] = sign * factor
                keys.append((("radii", getattr(inputs[k][1], "radii", None))
                             if part.m is not None else source) if driven else None)
            distinct = list(dict.fromkeys(key for key in keys if key is not None))
            if not distinct:        # a band no input drives: its modes, with a zero forcing
                distinct, keys = [0], [0] + [None] * (len(inputs) - 1)
            forced_orders = []
            for key in distinct:
                k = keys.index(key)
                force = (np.asarray(engine.electrode_forcing(state, part, inputs[k][1]), float)
                         if drives[k] else np.zeros(size))
                forced_orders.append(ForcedOrder.from_parts(part.pencil, force, zero, 0.0,
                                                            study.eigen.backend))
            built = ModalBasis.build_many(forced_orders, band.eigenvalues, band.vectors,
                                          labels, damping_per_mass)
            bases = dict(zip(distinct, zip(forced_orders, built)))
            forced0, basis0 = bases[distinct[0]]
            membrane_index = np.asarray(forced0.coupled.membrane_index)
            membrane = basis0.vectors[membrane_index]
            sound = model.part_pressure(engine, study, part, forced0, basis0,
                                        [bases.get(key, (forced0, None)) for key in keys])
            families = ("cos",) if part.m is None else ("cos", "sin")
            for family in families:
                gains = np.array([factors.get((family, k), 0.0) for k in range(len(inputs))])
                if not len(band.eigenvalues) and not np.any(gains):
                    continue        # no mode, no input drives this family
                family_labels = [next((mode.label for mode in columns[k]
                                       if part.m is None or mode.family == family), "")
                                 if k in columns else "" for k in range(len(labels))]
                model.channels.append(cls._channel(
                    f"{part.key}:{family}", part, family, bases, keys, gains,
                    family_labels, kinds, basis0, membrane, membrane_index, points,
                    sound if family == "cos" else _silent(sound)))
        model.channels = merged_static(model.channels)
        logger.info(f"modal model: {len(model.inputs)} input(s), {model.columns} band "
                    f"column(s) in {len(model.channels)} driven field(s), "
                    f"{len(model.point_names)} points")
        return model

    def part_pressure(self, engine, study, part, forced0, basis0, bases):
        """The kernels (3) on one driven part, per input before its family factor
        (``bases``: each input's (forced pencil, modal basis), the basis None for an input
        that does not drive the part): ``(P, P')`` of the columns (M, J), of r0 and of r1
        (M, K) each; zeros where the part does not radiate (module notes)."""
        from copdea_fem.forced_response.observers import LineResponse
        from copdea_fem.forced_response.run import microphone_observer

        count, columns = len(bases), basis0.vectors.shape[1]
        shapes = (columns, count, count)
        sound = tuple(np.zeros((2, len(self.microphones), size), complex) for size in shapes)
        if not (self.microphones and part.uniform and len(forced0.coupled.pressure_index)):
            return sound
        observer = microphone_observer(study, engine.driven_sector().sphere, part.pencil,
                                       self.microphones)
        none = np.zeros(basis0.residual0.shape, complex)
        residuals = [np.stack([none if basis[1] is None else getattr(basis[1], name)
                               for basis in bases], 1) for name in ("residual0", "residual1")]
        vectors = np.hstack([basis0.vectors] + residuals)
        f_max = float(study.eigen.f_max)
        own = np.abs(np.sqrt(basis0.eigenvalues.astype(complex)).real) / (2 * np.pi)
        lines = np.concatenate([np.linspace(f_max / KERNEL_FIT_LINES, f_max, KERNEL_FIT_LINES),
                                own[own <= f_max]])
        omega = 2 * np.pi * lines
        delay = np.exp(-1j * omega[:, None] * np.asarray(self.microphone_delays)[None, :])
        pressure = observer.column_pressure(LineResponse(forced0, vectors, np.eye(1)),
                                            lines) * delay[:, :, None]          # (F, M, n)
        size = np.abs(denominators(basis0.eigenvalues, basis0.norms, basis0.eigenvalues
                                   * basis0.damping_per_mass * basis0.structural_mass, omega))
        size = np.maximum(size, 1e-15 * size.max(axis=0, initial=0.0))   # an undamped peak
        weights = np.hstack([size.min(axis=0, initial=np.inf) / size,   # 1 / |d_j|, max 1
                             np.ones((lines.size, 2 * count))])
        fitted = fitted_kernels(omega, pressure, weights)                  # (2, M, n)
        return tuple(np.split(fitted, [columns, columns + count], axis=2))

    @staticmethod
    def _channel(name, part, family, bases, keys, gains, labels, kinds, basis0, membrane,
                 membrane_index, points, sound) -> Channel:
        """``bases``: forcing key -> (forced pencil, modal basis); ``keys``: each input's
        forcing key (None: the input does not drive the part); ``sound``: the part's
        pressure (:meth:`part_pressure`).  Each distinct forcing's static correction is
        sampled once, the inputs sharing it scaled by their factors ``gains``."""
        from copdea_fem.forced_response.observers import LineResponse

        operators = part.pencil.membrane
        count = len(gains)
        driven = [k for k in range(count) if keys[k] is not None and gains[k] != 0]
        distinct = list(dict.fromkeys(keys[k] for k in driven))
        where = {key: index for index, key in enumerate(distinct)}
        size, columns = basis0.vectors.shape

        def per_input(of):
            """(n, K) of ``of(basis)`` times each input's gain (zero where it does not
            drive)."""
            out = np.zeros((size, count), complex)
            for k in driven:
                out[:, k] = gains[k] * of(bases[keys[k]][1])
            return out

        participation = np.zeros((columns, count), complex)
        forcings = np.zeros((count, len(membrane_index)), complex)        # (K, n_membrane)
        for k in driven:
            forced, basis = bases[keys[k]]
            participation[:, k] = gains[k] * basis.participation
            forcings[k] = gains[k] * forced.forcing[membrane_index]
        currents = forcings @ membrane                                # (K, J)
        residual0 = per_input(lambda basis: basis.residual0)
        residual1 = per_input(lambda basis: basis.residual1)
        forced0 = next(iter(bases.values()))[0]
        own = [bases[key][1] for key in distinct]
        sampled = points.basis(LineResponse(forced0, np.hstack(
            [basis0.vectors] + [np.column_stack([basis.residual0 for basis in own]
                                                + [basis.residual1 for basis in own])]
            if own else [basis0.vectors]), np.zeros((1, 1))), operators, family)
        static0 = np.zeros(sampled.shape[:2] + (count,), complex)
        static1 = np.zeros_like(static0)
        for k in driven:
            index = columns + where[keys[k]]
            static0[..., k] = gains[k] * sampled[..., index]
            static1[..., k] = gains[k] * sampled[..., index + len(own)]
        return Channel(
            name=name, labels=labels,
            structural=np.array([kind != "air" and bool(label)
                                 for label, kind in zip(labels, kinds)]),
            out_of_plane=np.array([kind == OUT_OF_PLANE and bool(label)
                                   for label, kind in zip(labels, kinds)]),
            eigenvalues=basis0.eigenvalues, norms=basis0.norms,
            damping=basis0.eigenvalues * basis0.damping_per_mass * basis0.structural_mass,
            participation=participation,
            displacement=sampled[..., :columns],
            currents=currents,
            residual_displacement=static0,
            residual_displacement1=static1,
            residual_currents=forcings @ residual0[membrane_index],
            residual_currents1=forcings @ residual1[membrane_index],
            pressure=sound[0][0], pressure_rate=sound[0][1],
            residual_pressure=sound[1][0] * gains[None, :],
            residual_pressure_rate=sound[1][1] * gains[None, :],
            residual_pressure1=sound[2][0] * gains[None, :],
            residual_pressure1_rate=sound[2][1] * gains[None, :])

    @property
    def columns(self) -> int:
        """Band columns over all channels."""
        return sum(len(channel.eigenvalues) for channel in self.channels)

    def frequency_response(self, frequency_hz, static_correction: bool = True
                           ) -> tuple[np.ndarray, np.ndarray]:
        """The modal path (1) with its static correction (unless ``static_correction`` is
        false), physical ``e^{+i omega t}`` convention (the complex conjugate of the FE's):
        velocity (F, P, 3, K) [m/s/V] and motional current (F, K, K) [A/V] (row: the
        electrode sensed, column: the input)."""
        keep = 1.0 if static_correction else 0.0
        frequency_hz = np.atleast_1d(np.asarray(frequency_hz, float))
        omega = 2 * np.pi * frequency_hz
        count = len(self.inputs)
        velocity = np.zeros((omega.size, len(self.positions), 3, count), complex)
        current = np.zeros((omega.size, count, count), complex)
        for channel in self.channels:
            modal = channel.participation[None, :, :] / channel.denominators(omega)[:, :, None]
            displacement = (np.einsum("pdj,fjk->fpdk", channel.displacement, modal)
                            + keep * (channel.residual_displacement[None]
                                      + omega[:, None, None, None] ** 2
                                      * channel.residual_displacement1[None]))
            charge = (np.einsum("lj,fjk->flk", channel.currents, modal)
                      + keep * (channel.residual_currents[None]
                                + omega[:, None, None] ** 2 * channel.residual_currents1[None]))
            velocity += -1j * omega[:, None, None, None] * displacement
            current += -1j * omega[:, None, None] * charge
        return np.conj(velocity), np.conj(current)

    def pressure_response(self, frequency_hz, static_correction: bool = True) -> np.ndarray:
        """The pressure (3) at the microphones [Pa/V] (F, M, K), advanced by each
        microphone's ``|x_m| / c`` (module notes), physical ``e^{+i omega t}`` convention."""
        keep = 1.0 if static_correction else 0.0
        omega = 2 * np.pi * np.atleast_1d(np.asarray(frequency_hz, float))
        pressure = np.zeros((omega.size, len(self.microphones), len(self.inputs)), complex)
        for channel in self.channels:
            modal = channel.participation[None, :, :] / channel.denominators(omega)[:, :, None]
            columns, residual0, residual1 = channel.pressure_kernels(omega)
            pressure += (np.einsum("fmj,fjk->fmk", columns, modal)
                         + keep * (residual0 + omega[:, None, None] ** 2 * residual1))
        return np.conj(pressure)

    def structural_modes(self, f_max: float, out_of_plane: bool = False
                         ) -> list[tuple[int, int, str, float]]:
        """``(channel index, column, label, Re f [Hz])`` of the labelled structural modes
        (``out_of_plane``: the out-of-plane ones only) with ``Re f <= f_max``, by
        frequency."""
        found = []
        for c, channel in enumerate(self.channels):
            freq = np.sqrt(channel.eigenvalues.astype(complex)) / (2 * np.pi)
            freq = np.where(freq.real < 0, -freq, freq)
            kept = channel.out_of_plane if out_of_plane else channel.structural
            for j in np.flatnonzero(kept):
                if freq[j].real <= f_max:
                    found.append((c, int(j), channel.labels[j], float(freq[j].real)))
        return sorted(found, key=lambda item: (item[3], item[2]))


#: A family factor of an order m >= 1 at most this share of the largest a weight can have
#: there, ``2 / (pi m)`` (a segment's ``|c_m + i s_m|``, eq. 4 of
#: :mod:`copdea_fem.fe.forced.electrode`), is round-off: the sines of angles up to
#: ``2 pi m`` carry ~``1e-16 * 2 pi m`` (1e-13 of it at m = 120; e.g. the even orders of a
#: half turn), and the input is taken not to drive the family.
FACTOR_ROUND_OFF = 1e-10


#: The lines up to ``eigen.f_max`` on which the pressure kernels (3) are fitted, besides each
#: column's own frequency: the kernels vary on the scale ``c / (sphere radius)`` (a few
#: kHz), so 16 lines hold them (measured: the error of the modal path's far pressure moved
#: by 0.2 % of the peak from 4 to 64 lines).
KERNEL_FIT_LINES = 16


def denominators(eigenvalues, norms, damping, omega) -> np.ndarray:
    """d_j(omega) of (1) (F, J), FE convention, at ``omega`` [rad/s] (F,)."""
    omega = np.asarray(omega, float)[:, None]
    return norms[None, :] * (eigenvalues[None, :] - omega ** 2) - 1j * omega * damping[None, :]


def fitted_kernels(omega, pressure, weights) -> np.ndarray:
    """(P, P') of (3) (2, M, n): per column, the weighted least-squares fit of
    ``P + (-i omega) P'`` to ``pressure`` (F, M, n) at ``omega`` [rad/s] (F,), line f of
    column j weighted by ``weights[f, j]``."""
    basis = np.stack([np.ones(omega.size), -1j * omega], axis=1)         # (F, 2)
    fitted = np.zeros((2,) + pressure.shape[1:], complex)
    for j in range(pressure.shape[2]):
        weight = weights[:, j:j + 1]
        fitted[:, :, j] = np.linalg.lstsq(basis * weight, pressure[:, :, j] * weight,
                                          rcond=None)[0]
    return fitted


def driven_families(part, weight) -> list[tuple[str, float]]:
    """``part.families(weight)`` (:meth:`copdea_fem.fe.forced.problem.DrivenPart.families`)
    without the factors of an order m >= 1 at the round-off level,
    :data:`FACTOR_ROUND_OFF` times ``2 / (pi m)``."""
    families = part.families(weight)
    if not part.m:
        return families
    floor = FACTOR_ROUND_OFF * 2 / (np.pi * part.m)
    return [(family, factor) for family, factor in families if abs(factor) > floor]


def mirrored_inputs(inputs, sector) -> dict:
    """``{k: (j, sign)}``: input k's weight is input j's (j < k, itself not mirrored)
    mirrored in an axis of the quadrant's symmetry
    (:meth:`copdea_fem.fe.forced.electrode.SegmentWeight.mirror_of`), so on ``sector`` (a
    :class:`copdea_fem.fe.symmetry.Sector`) its folded weight, hence its forcing, is
    ``sign = s(qx, qy)`` times j's, exactly (the indicator's values at mirrored points); the
    eight 45-degree sectors of a turn need two forcings per sector, not eight.  None on the
    whole device (``sector`` None: no folding)."""
    if sector is None:
        return {}
    mirrors = {}
    for k, (_, weight) in enumerate(inputs):
        for j in range(k):
            if j in mirrors:
                continue
            reflection = inputs[j][1].mirror_of(weight)
            if reflection is not None:
                mirrors[k] = (j, float(sector.sign(*reflection)))
                break
    return mirrors


def microphone_delays(study, microphones) -> list[float]:
    """The delay [s] each microphone's pressure is advanced by in the model (eq. 3):
    ``|x_m| / c`` for one the Kirchhoff integral reaches, 0 for one inside its sphere (the
    FE's own pressure there: a constant gain, exact;
    :func:`.microphone_places.microphone_places`)."""
    from copdea_fem.forced_response.microphone_places import FAR, microphone_places
    return [float(np.linalg.norm(position)) / study.air.sound_speed if place == FAR else 0.0
            for (_, position), place in zip(microphones, microphone_places(study, microphones))]


#: ``max_modes_per_shift`` of the radiating band's solve (:func:`copdea_fem.fe.eigen.solve_band`'s
#: default).  A pencil of at most three times this many unknowns (an order of the
#: axisymmetric engine: 225 on the quick G1) is asked a third of its size at the first
#: shift, which the planner answers by its dense QZ at once: the band (the air and PML
#: modes up to ``modal_band f_max`` in both directions, 22 of 225) holds more than a first
#: Krylov run of 20, after which the planner went dense anyway (80 solves, 0.05-0.1 s, for
#: nothing; the pairs are the same, bit for bit).
RADIATING_MODES_PER_SHIFT = 80


def radiating_band(part, study):
    """``part`` (the one a uniform electrode drives, with air) with the band of
    ``response``'s modal path (:func:`.run.modal_solution`): ``Re f`` and ``|Im f|`` up to
    ``response.modal_band`` times ``eigen.f_max``, the strongly damped air and PML modes
    included; the sound at a microphone is theirs as much as the structure's, and
    ``solve``'s band (``|Im f| <= eigen.max_damping_ratio f_max``) leaves them to the
    static correction (measured on the quick G1 in a baffle: 25 % of the peak pressure)."""
    import dataclasses
    import types

    from copdea_fem.fe.eigen import solve_band

    eigen, pencil = study.eigen, part.pencil
    reach = study.response.modal_band * eigen.f_max
    logger.info(f"{part.key}: the radiating modes for the sound, Re f <= {reach:g} Hz, "
                f"|Im f| <= {reach:g} Hz ...")
    size = pencil.stiffness.shape[0]
    found = solve_band(pencil.stiffness, pencil.mass, 0.0, reach, factorize=pencil.factorize,
                       hermitian=False, max_imag_hz=reach, backend=eigen.backend,
                       max_modes=eigen.max_modes, residual_tol=eigen.residual_tol,
                       max_modes_per_shift=RADIATING_MODES_PER_SHIFT,
                       start_modes=size // 3 if size // 3 <= RADIATING_MODES_PER_SHIFT
                       else None)
    band = types.SimpleNamespace(eigenvalues=np.asarray(found.eigenvalues),
                                 vectors=np.asarray(found.vectors))
    return dataclasses.replace(part, band=band)


def _silent(sound):
    """The kernels (:meth:`ModalInputs.part_pressure`) of a field that does not radiate
    (an order's sin family: the part's radiating field is its cos family)."""
    return tuple(np.zeros_like(array) for array in sound)


#: The name of the channel that holds the static correction of the driven parts without a
#: mode in the band (:func:`merged_static`).
STATIC_CHANNEL = "static:parts without a band mode"


def merged_static(channels: list) -> list:
    """``channels`` with those without a band column (the orders a segment drives above the
    band: :meth:`copdea_fem.fe.engines.Engine.driven_parts`) summed into one,
    :data:`STATIC_CHANNEL`: their response is their static correction ``r0_k + omega^2
    r1_k`` alone, linear in the inputs, so the sum is exact (and the state space holds one
    pseudo-mode per input for all of them, not one per order)."""
    static = [channel for channel in channels if len(channel.eigenvalues) == 0]
    if len(static) < 2:
        return channels
    first = static[0]
    summed = {name: sum(getattr(channel, name) for channel in static) for name in (
        "residual_displacement", "residual_displacement1", "residual_currents",
        "residual_currents1", "residual_pressure", "residual_pressure_rate",
        "residual_pressure1", "residual_pressure1_rate")}
    merged = Channel(name=STATIC_CHANNEL, labels=[], structural=first.structural,
                     out_of_plane=first.out_of_plane, eigenvalues=first.eigenvalues,
                     norms=first.norms, damping=first.damping,
                     participation=first.participation, displacement=first.displacement,
                     currents=first.currents, pressure=first.pressure,
                     pressure_rate=first.pressure_rate, **summed)
    return [channel for channel in channels if len(channel.eigenvalues)] + [merged]


__all__ = ["Channel", "FACTOR_ROUND_OFF", "KERNEL_FIT_LINES", "ModalInputs", "POINT_ANGLES_DEG",
           "RADIATING_MODES_PER_SHIFT", "STATIC_CHANNEL",
           "denominators", "drive_inputs", "fitted_kernels", "mirrored_inputs", "driven_families", "merged_static", "microphone_delays",
           "radiating_band", "study_points"]
