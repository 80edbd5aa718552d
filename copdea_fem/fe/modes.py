"""Mode post-processing: out-of-plane / in-plane / pumping, (m, n) labels, modal mass.

Labels follow DESIGN.md: ``(m, n)`` = m nodal diameters (circumferential
wavenumber, from the Fourier content of the normal displacement around the
membrane) and radial order n (n - 1 interior nodal circles, counted along the
radius in the dominant Fourier component).  Two modes with the same (m, n)
(the cos/sin pair of a circular membrane, split slightly by a square frame)
are ``(m,n)a`` and ``(m,n)b``, named by what each mode is, never by its rank in
the band (:func:`assign_labels`): ``a`` the cos m theta member (normal
displacement even about y = 0), ``b`` the sin m theta one.  Pumping modes (the
disc carries most of the kinetic energy) are ``P1, P2, ...``; in-plane modes
``ip(m,n)`` take n from their dominant in-plane component and the letters
``a``/``b`` (hoop-dominant, cos/sin) or ``c``/``d`` (radial-dominant, cos/sin);
at m = 0 ``a`` is the torsion, ``b`` the radial mode.  A pair an imperfection splits and
turns (:mod:`copdea_fem.study.imperfections`) keeps the rule: ``a`` is the member closer to
cos m theta; :attr:`Mode.orientation_deg` says where each member's antinode lies.

Energy fractions are kinetic-energy (mass-weighted) fractions, exact FE
integrals: ``normal_fraction = x^H M_n x / x^H M x`` over the membrane with
``M_n = rho_s * integral of (u.n)(v.n) dS`` and n the deformed normal;
``disc_fraction = (M_d + M_s/3) |w_d|^2 / x^H M x``, the rigid disc's share.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import math

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.cavity import CAVITY_MEMBRANE_ENERGY
from copdea_fem.fe.linearise import MembraneOperators, to_scipy
from copdea_fem.fe.membrane import areal_density, deformed_normal

OUT_OF_PLANE, IN_PLANE, PUMPING, AIR = "out-of-plane", "in-plane", "pumping", "air"
PUMPING_DISC_FRACTION = 0.5   # disc kinetic energy share above which a mode is pumping
OUT_OF_PLANE_FRACTION = 0.5   # normal kinetic energy share above which a mode is out-of-plane
NODE_THRESHOLD = 0.02         # |W_m(r)| below this share of its peak is not a sign


@dataclass
class Mode:
    """One mode with its classification; displacement normalised to peak |u| = 1."""

    index: int
    freq_hz: float
    freq_im_hz: float
    residual: float
    kind: str
    m: int
    n: int
    label: str
    normal_fraction: float
    disc_fraction: float
    modal_mass: float              # kg, for unit peak normal (pumping: disc) displacement
    vector: np.ndarray = field(repr=False)   # full membrane-space coefficients
    disc_displacement: complex = 0.0
    membrane_energy_fraction: float = 1.0    # kinetic energy share of the membrane (+ disc)
    # copdea_fem.fe.symmetry.Sector on a quadrant mesh (vector: quadrant part)
    sector: object = None
    family: str = ""               # "cos" / "sin": normal and radial parts go as cos / sin m theta
    in_plane_component: str = ""   # in-plane modes: "radial" or "hoop", the dominant component
    # an air mode inside an enclosure: its (m, n, p) (copdea_fem.fe.cavity); () otherwise
    cavity_orders: tuple = ()
    # deg, the angle of an antinode line in [0, 180/m) from the shape (mode_orientation)
    orientation: float = math.nan

    @property
    def orientation_deg(self) -> float:
        """Angle [deg] counter-clockwise from x of the member's first antinode line (its
        largest |displacement| round a circle), in ``[0, 180/m)``: measured from the shape
        where the engine sampled it (:func:`mode_orientation`), else from its family (a cos
        member 0, a sin member 90/m); NaN for m = 0 (no orientation)."""
        if self.m == 0:
            return math.nan
        if not math.isnan(self.orientation):
            return self.orientation
        if self.family in ("cos", "sin"):
            return 0.0 if self.family == "cos" else 90.0 / self.m
        return math.nan

    @property
    def damping_ratio(self) -> float:
        """zeta = -Im f / |f| [-]: fields go as e^{-i omega t} (NGSolve's PML convention),
        so a decaying (radiating) mode has Im f < 0; 0 for dry modes."""
        magnitude = float(np.hypot(self.freq_hz, self.freq_im_hz))
        return float(-self.freq_im_hz / magnitude) if magnitude > 0 else 0.0


class ModeSampler:
    """Evaluates membrane fields on a polar grid of the whole reference plane.

    On a quadrant mesh the grid is folded into the quadrant and a sector's
    field is unfolded with its parity signs (:mod:`copdea_fem.fe.symmetry`):
    normal and radial components take s(q), the hoop component s(q) q_x q_y
    (e_theta flips under each reflection).  Grid points that fold onto the same
    quadrant point (theta, pi - theta, pi + theta, -theta: 64 angles hold 17
    distinct ones) are evaluated once.

    A sampler describes one prestressed state (the deformed normal, the normal
    mass matrix): make a new one after the state moves.
    """

    def __init__(self, state, n_radii: int = 40, n_angles: int = 64):
        r_o, r_i = state.outer_radius, state.inner_radius
        inner = max(r_i, 0.02 * r_o)
        self.radii = inner + (r_o - inner) * (np.arange(n_radii) + 0.5) / n_radii
        self.angles = 2 * np.pi * np.arange(n_angles) / n_angles
        rr, tt = np.meshgrid(self.radii, self.angles, indexing="ij")
        xs, ys, self._qx, self._qy = state.symmetry.fold(rr.ravel() * np.cos(tt.ravel()),
                                                         rr.ravel() * np.sin(tt.ravel()))
        # folded copies agree to round-off in cos/sin: merge them on a 1e-9 r_o grid
        keys = np.round(np.stack([xs, ys], axis=1) / (1e-9 * r_o)).astype(np.int64)
        _, first, self._copy_of = np.unique(keys, axis=0, return_index=True,
                                            return_inverse=True)
        self._copy_of = self._copy_of.ravel()
        self.points = state.mesh(xs[first], ys[first], np.zeros(first.size), ngs.BND)
        self.shape = rr.shape
        self._state = state
        self._normal_mass = None
        self.gf = ngs.GridFunction(state.space)
        normal = deformed_normal(state.displacement)
        radial = ngs.CF((ngs.x, ngs.y, 0)) / ngs.sqrt(ngs.x**2 + ngs.y**2)
        hoop = ngs.CF((-ngs.y, ngs.x, 0)) / ngs.sqrt(ngs.x**2 + ngs.y**2)
        self._components = ngs.CF((self.gf * normal, self.gf * radial, self.gf * hoop)).Compile()

    def components(self, vector: np.ndarray, sector=None) -> np.ndarray:
        """(normal, radial, hoop) displacement on the grid: array (3, n_radii, n_angles).

        ``sector``: the symmetry class of ``vector`` on a quadrant mesh.
        """
        values = []
        for part in (np.real(vector), np.imag(vector)) if np.iscomplexobj(vector) else (vector,):
            self.gf.vec.FV().NumPy()[:] = part
            values.append(np.asarray(self._components(self.points))[self._copy_of])
        field_ = values[0] + 1j * values[1] if len(values) == 2 else values[0]
        if sector is not None:
            sign = sector.sign(self._qx, self._qy)
            field_ = field_ * np.stack([sign, sign, sign * self._qx * self._qy], axis=1)
        return np.moveaxis(field_.reshape(*self.shape, 3), -1, 0)

    @property
    def normal_mass(self):
        """:func:`normal_mass_matrix` of the sampler's state, assembled on first use [kg]."""
        if self._normal_mass is None:
            self._normal_mass = normal_mass_matrix(self._state)
        return self._normal_mass


def circumferential_order(field_: np.ndarray, radii: np.ndarray) -> tuple[int, np.ndarray]:
    """Dominant circumferential wavenumber m of a (n_radii, n_angles) field, and W_m(r)."""
    spectrum = np.fft.fft(field_, axis=1) / field_.shape[1]
    half = field_.shape[1] // 2
    power = np.abs(spectrum[:, : half + 1]) ** 2
    power[:, 1:half] += np.abs(spectrum[:, -1:-half:-1]) ** 2
    weighted = (power * radii[:, None]).sum(axis=0)
    m = int(np.argmax(weighted))
    return m, spectrum[:, m] if np.abs(spectrum[:, m]).max() >= np.abs(spectrum[:, -m]).max() \
        else spectrum[:, -m]


def radial_order(profile: np.ndarray) -> int:
    """n = 1 + sign changes of a complex radial profile after phase alignment."""
    peak = profile[np.argmax(np.abs(profile))]
    real = np.real(profile * np.conj(peak) / abs(peak)) if abs(peak) > 0 else np.real(profile)
    significant = real[np.abs(real) > NODE_THRESHOLD * np.abs(real).max()]
    return 1 + int(np.count_nonzero(np.diff(np.sign(significant)) != 0))


def normal_mass_matrix(state):
    """M_n = rho_s * integral (u.n)(v.n) dS on the deformed normal [kg] (SciPy, full space)."""
    u, v = state.space.TnT()
    normal = deformed_normal(state.displacement)
    form = ngs.BilinearForm(areal_density(state.material) * (u * normal) * (v * normal)
                            * state.measure)
    return to_scipy(form.Assemble().mat)


def classify_modes(operators: MembraneOperators, eigen_result, sampler: ModeSampler | None = None
                   ) -> list[Mode]:
    """Turn eigenpairs of (K_s, M_s) into labelled, normalised :class:`Mode` objects."""
    state = operators.state
    sampler = sampler or ModeSampler(state)
    copies = state.symmetry.copies      # a quadrant's masses are a quarter of the device's
    full = operators.to_full(eigen_result.vectors)
    normal_mass = sampler.normal_mass
    modes = []
    for k in range(full.shape[1]):
        reduced = eigen_result.vectors[:, k]
        total = float(np.real(np.vdot(reduced, operators.mass @ reduced)))
        disc = complex(reduced[-1]) if operators.disc_dof else 0.0
        # the rigid disc's own (lumped) mass only: mass[-1, -1] also holds the membrane
        # mass the rim lift carries, a mesh-dependent strip of the membrane
        disc_energy = operators.disc_mass * abs(disc) ** 2
        vector = full[:, k]
        normal_energy = float(np.real(np.vdot(vector, normal_mass @ vector)))
        membrane_energy = max(total - disc_energy, 1e-300)
        normal_fraction = normal_energy / membrane_energy
        disc_fraction = disc_energy / total
        normal, radial, hoop = sampler.components(vector, operators.sector)
        if disc_fraction > PUMPING_DISC_FRACTION:
            kind, field_ = PUMPING, normal
        elif normal_fraction >= OUT_OF_PLANE_FRACTION:
            kind, field_ = OUT_OF_PLANE, normal
        else:
            kind = IN_PLANE
            field_ = radial if np.sum(np.abs(radial) ** 2) >= np.sum(np.abs(hoop) ** 2) else hoop
        m, profile = circumferential_order(field_, sampler.radii)
        n = radial_order(profile)
        component = "" if kind != IN_PLANE else ("radial" if field_ is radial else "hoop")
        family = sector_family(m, operators.sector) if operators.sector is not None else \
            field_family(field_, m, sampler.angles, hoop=field_ is hoop)
        peak_normal = float(np.abs(normal).max())
        reference = abs(disc) if kind == PUMPING else (peak_normal if kind == OUT_OF_PLANE else
                                                       float(np.abs([radial, hoop]).max()))
        scale = 1.0 / reference if reference > 0 else 1.0
        peak = float(np.abs(np.stack([normal, radial, hoop])).max()) * scale
        modes.append(Mode(
            index=k, freq_hz=float(eigen_result.freq_hz[k]),
            freq_im_hz=float(eigen_result.freq_im_hz[k]),
            residual=float(eigen_result.residuals[k]), kind=kind, m=m, n=n, label="",
            normal_fraction=normal_fraction, disc_fraction=disc_fraction,
            modal_mass=copies * total * scale**2, vector=vector * scale / max(peak, 1e-300),
            disc_displacement=disc * scale / max(peak, 1e-300), sector=operators.sector,
            family=family, in_plane_component=component,
            orientation=mode_orientation(field_, m, sampler.angles, sampler.radii,
                                         hoop=field_ is hoop)))
    assign_labels(modes)
    return modes


def sector_family(m: int, sector) -> str:
    """``"cos"`` / ``"sin"`` member of a pair from its mirror class: a cos m theta normal
    displacement is even about y = 0 (:func:`copdea_fem.fe.axisymmetric.modes.family_sector`);
    an m = 0 mode has only one member, ``"cos"``."""
    return "cos" if m == 0 or sector.parity_y == 1 else "sin"


def field_family(field_: np.ndarray, m: int, angles: np.ndarray, hoop: bool = False) -> str:
    """``"cos"`` / ``"sin"`` member of a pair on a whole mesh (any orientation): whichever of
    cos m theta and sin m theta carries more of the (n_radii, n_angles) field; the hoop
    component of the cos member goes as sin m theta (``hoop=True`` swaps them).  The two
    members of a pair are orthogonal, so they fall on different sides (a pair turned by
    exactly pi/(4m) is the tie, broken towards cos)."""
    if m == 0:
        return "cos"
    cos_part = float(np.sum(np.abs(field_ @ np.cos(m * angles)) ** 2))
    sin_part = float(np.sum(np.abs(field_ @ np.sin(m * angles)) ** 2))
    return "cos" if (cos_part >= sin_part) != hoop else "sin"


def mode_orientation(field_: np.ndarray, m: int, angles: np.ndarray, radii: np.ndarray,
                     hoop: bool = False) -> float:
    """The orientation [deg, in [0, 180/m)] of a (n_radii, n_angles) field's order-m part
    (:attr:`Mode.orientation_deg`); NaN for m = 0.

    With ``A(r) = sum f cos m theta`` and ``B(r) = sum f sin m theta`` (complex: a damped
    mode's shape), the field's order-m part is ``A cos m theta + B sin m theta``; the
    radius-weighted 2x2 matrix ``S = sum_r r Re[(A, B)^H (A, B)]`` has its principal
    eigenvector along ``(cos psi, sin psi)`` for a shape ``cos m (theta - psi/m)``: its
    antinode at ``psi/m`` (defined mod 180/m: the eigenvector's sign).  The hoop component
    of the cos member goes as sin m theta, so it is turned back by 90/m."""
    if m == 0:
        return math.nan
    a, b = field_ @ np.cos(m * angles), field_ @ np.sin(m * angles)
    cross = np.sum(radii * np.real(a * np.conj(b)))
    matrix = np.array([[np.sum(radii * np.abs(a) ** 2), cross],
                       [cross, np.sum(radii * np.abs(b) ** 2)]])
    _, vectors = np.linalg.eigh(matrix)
    psi = math.atan2(vectors[1, -1], vectors[0, -1])
    angle = math.degrees(psi) / m - (90.0 / m if hoop else 0.0)
    period = 180.0 / m
    angle %= period
    return 0.0 if period - angle < 1e-9 * period else angle


def pair_letter(mode: Mode) -> str:
    """The letter of a labelled mode, from what the mode is (module doc): out-of-plane
    ``a``/``b`` = cos/sin member (none for m = 0); in-plane ``a``/``b`` hoop-dominant
    (shear), ``c``/``d`` radial-dominant, cos/sin member, and at m = 0 (one member each)
    ``a`` the hoop-dominant (torsion), ``b`` the radial one; ``""`` when the family is
    unknown.  (Shear modes lie below the radial ones of the same (m, n) in a tensioned
    membrane, so a band from 0 Hz reads a, b, c, d in frequency order.)"""
    if mode.family not in ("cos", "sin"):
        return ""
    if mode.kind == OUT_OF_PLANE:
        return "" if mode.m == 0 else "ab"[mode.family == "sin"]
    radial = mode.in_plane_component == "radial"
    if mode.m == 0:
        return "ab"[radial]
    return "abcd"[2 * radial + (mode.family == "sin")]


def assign_labels(modes: list[Mode]) -> None:
    """(m,n) / ip(m,n) / P_k labels (module doc).

    The letters come from the mode (:func:`pair_letter`), so a mode keeps its label
    whatever band holds it.  Modes whose family is unknown take ``a, b, ...`` in
    frequency order among their (m, n), and two modes that would share one label
    (a classification the rule cannot tell apart) keep it with ``-2``, ``-3`` appended
    in frequency order, so labels stay unique.
    """
    pumping = 0
    seen: dict[str, list[Mode]] = {}
    for mode in sorted(modes, key=lambda mode: mode.freq_hz):
        if mode.kind == PUMPING:
            pumping += 1
            mode.label = f"P{pumping}"
            continue
        base = f"({mode.m},{mode.n})" if mode.kind == OUT_OF_PLANE else f"ip({mode.m},{mode.n})"
        seen.setdefault(base, []).append(mode)
    for base, group in seen.items():
        letters = [pair_letter(mode) for mode in group]
        if group[0].kind == OUT_OF_PLANE and group[0].m == 0 or all(letters):
            used: dict[str, int] = {}
            for mode, letter in zip(group, letters):
                label = base + letter
                used[label] = used.get(label, 0) + 1
                mode.label = label if used[label] == 1 else f"{label}-{used[label]}"
        elif len(group) == 1:
            group[0].label = base
        else:
            for suffix, mode in zip("abcdefghijklmnopqrstuvwxyz", group):
                mode.label = base + suffix


# -- coupled modes (post-processing of the coupled pencil's eigenpairs) ---------------
@dataclass
class _MembranePart:
    """Membrane part of coupled eigenpairs, shaped like a
    :class:`copdea_fem.fe.eigen.BandResult` for this module."""

    vectors: np.ndarray
    freq_hz: np.ndarray
    freq_im_hz: np.ndarray
    residuals: np.ndarray


def membrane_energy_fractions(coupled, result) -> list[float]:
    """Membrane (+ disc) share of the kinetic energy of each coupled eigenpair [-].

    Time-averaged kinetic energies, exact integrals: ``KE_m = |lambda| u^H M_s u``,
    ``KE_a = beta^2 p^^H K_a0 p^ / |lambda|`` with ``K_a0`` the air stiffness over the
    physical air (no PML).  ``coupled``: the coupled operators of either engine
    (``membrane.mass``, ``air_kinetic``, ``membrane_index``, ``pressure_index``,
    ``pressure_scale``).
    """
    membrane_vectors = result.vectors[coupled.membrane_index]
    pressure_vectors = result.vectors[coupled.pressure_index] * coupled.pressure_scale
    fractions = []
    for k, eigenvalue in enumerate(np.asarray(result.eigenvalues)):
        u, p = membrane_vectors[:, k], pressure_vectors[:, k]
        magnitude = max(abs(eigenvalue), 1e-300)
        kinetic_membrane = magnitude * float(np.real(np.vdot(u, coupled.membrane.mass @ u)))
        kinetic_air = float(np.real(np.vdot(p, coupled.air_kinetic @ p))) / magnitude
        fractions.append(kinetic_membrane / max(kinetic_membrane + kinetic_air, 1e-300))
    return fractions


def coupled_mode_list(coupled, result, min_membrane_energy: float,
                      sampler: ModeSampler) -> tuple[list[Mode], list[np.ndarray]]:
    """Classify coupled eigenpairs of the 3-D engine
    (:class:`copdea_fem.fe.coupled.CoupledOperators`); returns modes and their pressure
    vectors [Pa, free DOFs] (:func:`membrane_energy_fractions` decides the air modes)."""
    membrane_vectors = result.vectors[coupled.membrane_index]
    pressure_vectors = result.vectors[coupled.pressure_index] * coupled.pressure_scale
    fractions = membrane_energy_fractions(coupled, result)
    part = _MembranePart(membrane_vectors, np.asarray(result.freq_hz),
                         np.asarray(result.freq_im_hz), np.asarray(result.residuals))
    modes = classify_modes(coupled.membrane, part, sampler)
    pressures = []
    full = coupled.membrane.to_full(membrane_vectors)
    for mode, fraction, k in zip(modes, fractions, range(len(modes))):
        mode.membrane_energy_fraction = fraction
        scale = np.linalg.norm(mode.vector) / max(np.linalg.norm(full[:, k]), 1e-300)
        pressures.append(pressure_vectors[:, k] * scale)
        if fraction < min_membrane_energy:
            mode.kind, mode.label, mode.m, mode.n = AIR, "air", 0, 0
    structural = [mode for mode in modes if mode.kind != AIR]
    assign_labels(structural)
    return modes, pressures


def may_be_cavity_mode(mode) -> bool:
    """Whether a coupled :class:`Mode` moves mostly air (an air mode or a membrane share
    below :data:`copdea_fem.fe.cavity.CAVITY_MEMBRANE_ENERGY`): a cavity mode when most of
    its air's potential energy lies inside the enclosure (:mod:`copdea_fem.fe.cavity`)."""
    return mode.kind == AIR or mode.membrane_energy_fraction < CAVITY_MEMBRANE_ENERGY


def number_from_dry_partners(modes: list[Mode], dry_modes: list[Mode], mass) -> None:
    """n of coupled out-of-plane modes from their dry partners: the one-to-one assignment of
    largest total MAC (:func:`largest_mac_assignment`) between the coupled out-of-plane
    modes and the dry ones of one order (or sector and m).

    A wet mode is the dry one the air loads: its n is the dry mode's, whatever its shape
    became.  Over an enclosure the trapped air stiffens the volume-changing (0,1) past the
    (0,2) and bends it to a net volume near zero, with a nodal circle of its own
    (docs/enclosures.md): counted, it would read (0,2) or (0,3).  Cavity modes
    (:attr:`Mode.cavity_orders`, a vent's Helmholtz mode among them) are no membrane mode
    and take no n; with no dry out-of-plane mode the modes keep their n.
    """
    wet = [mode for mode in modes if mode.kind == OUT_OF_PLANE and not mode.cavity_orders]
    dry = [mode for mode in dry_modes if mode.kind == OUT_OF_PLANE]
    if not wet or not dry:
        return
    macs = np.array([[mac(w.vector, d.vector, mass) for d in dry] for w in wet])
    rows, columns = largest_mac_assignment(macs)
    for row, column in zip(rows, columns):
        wet[row].n = dry[column].n


def largest_mac_assignment(macs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the one-to-one assignment of largest total MAC in ``macs``
    (wet x dry, MAC [-]; rows ascending).

    SciPy's sparse bipartite matching
    (:func:`scipy.sparse.csgraph.min_weight_full_bipartite_matching`, LAPJVsp) on the dense
    table: the same optimum as :func:`scipy.optimize.linear_sum_assignment` with
    ``maximize=True``, without importing all of :mod:`scipy.optimize` into a solve (0.1-0.2 s
    of a small command).  Every MAC is shifted by 1, so that a MAC of exactly 0 stays an
    edge of the graph (a zero is no edge there); every full matching holds min(rows,
    columns) edges, so the shift moves every total alike and keeps the optimum.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching
    transposed = macs.shape[0] > macs.shape[1]
    table = macs.T if transposed else macs          # rows: the smaller side
    rows, columns = min_weight_full_bipartite_matching(csr_matrix(table + 1.0), maximize=True)
    if not transposed:
        return rows, columns
    order = np.argsort(columns)
    return columns[order], rows[order]


def same_family(mode: Mode, dry: Mode) -> bool:
    """The 3-D engine's pairing rule: same kind, (m, n) and symmetry sector."""
    return dry.kind == mode.kind and (dry.m, dry.n) == (mode.m, mode.n) and \
        dry.sector == mode.sector


def match_dry(modes: list[Mode], dry_modes: list[Mode], membrane_mass,
              same=same_family) -> dict[int, Mode]:
    """Dry partner of every structural coupled mode: same (m, n) family, best MAC.

    MAC = |u_c^H M u_d|^2 / (u_c^H M u_c * u_d^H M u_d) on the full membrane
    vectors (on a quadrant mesh: within the mode's symmetry sector); within a degenerate
    pair the subspace is what matters, so pairs share the dry pair's frequencies (they
    are equal up to the mesh).  ``same(mode, dry)`` says which dry modes may pair.
    """
    partners = {}
    used: set[int] = set()
    for k, mode in enumerate(modes):
        if mode.kind == AIR or mode.cavity_orders:      # no membrane mode: no dry partner
            continue
        best, best_mac = None, -1.0
        for j, dry in enumerate(dry_modes):
            if j in used or not same(mode, dry):
                continue
            value = mac(mode.vector, dry.vector, membrane_mass)
            if value > best_mac:
                best, best_mac = j, value
        if best is not None:
            used.add(best)
            partners[k] = dry_modes[best]
    return partners


def mac(a, b, mass) -> float:
    """Modal assurance criterion |a^H M b|^2 / (a^H M a b^H M b) [-]."""
    cross = np.vdot(a, mass @ b)
    return float(abs(cross) ** 2 / max(np.real(np.vdot(a, mass @ a) * np.vdot(b, mass @ b)),
                                       1e-300))
