"""Verification of the air model: PML, pressure-jump space, forms (rung 4 of the ladder).

Closed forms are written for NGSolve's time convention ``e^{-i omega t}``
(textbook ``e^{+j omega t}`` forms complex-conjugated, see acoustics module doc).
A prescribed normal velocity ``v0`` is a displacement ``u . n = i v0 / omega``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import j1, struve

from copdea_fem.fe import acoustics
from copdea_fem.fe.quadrant.geometry import GeometrySpec, load_mesh
from copdea_fem.fe.symmetry import Symmetry
from copdea_fem.study import parse_study

ngsolve = pytest.importorskip("ngsolve")

DEFAULTS = parse_study({})
DENSITY = DEFAULTS.air.density          # rho_a [kg/m^3]
SOUND_SPEED = DEFAULTS.air.sound_speed  # c_a [m/s]
OUTER_RADIUS = DEFAULTS.geometry.outer_radius  # r_o [m]
FREQUENCIES = (200.0, 500.0, 1000.0)          # [Hz], the band of the coupled (0,1), (0,2) modes
PRESSURE_ORDER = 2


@pytest.fixture(scope="session")
def mesh_cache(tmp_path_factory):
    """Mesh cache outside the repository's meshes/."""
    return tmp_path_factory.mktemp("meshes")


def _solve(mesh, space, frequency, load):
    """Solve ``k_a - omega^2 m_a = load`` for the pressure; return its GridFunction."""
    omega = 2 * math.pi * frequency
    trial, test = space.TrialFunction(), space.TestFunction()
    system = ngsolve.BilinearForm(space)
    system += (acoustics.air_stiffness(trial, test, DENSITY)
               - omega**2 * acoustics.air_mass(trial, test, DENSITY, SOUND_SPEED))
    system.Assemble()
    rhs = ngsolve.LinearForm(space)
    rhs += load(test, omega)
    rhs.Assemble()
    solution = ngsolve.GridFunction(space)
    solution.vec.data = system.mat.Inverse(space.FreeDofs(), inverse="umfpack") * rhs.vec
    return solution


# --------------------------------------------------------------------------- PML

def test_unbounded_pml_jacobian_matches_finite_differences():
    """The hand-written Jacobian of the custom stretch is the derivative of the map."""
    from netgen.csg import unit_cube

    mesh = ngsolve.Mesh(unit_cube.GenerateMesh(maxh=0.5))   # the CFs need mesh points
    R, t = 0.5, 0.3                                         # shell inside the unit cube
    stretch = acoustics.radial_pml(R, t, strength=7.0)

    def mapped(point):
        return np.array(stretch.PML_CF(mesh(*point)))

    step = 1e-6
    for point in ((0.4, 0.3, 0.35), (0.55, 0.1, 0.2), (0.2, 0.3, 0.65)):
        jac = np.array(stretch.Jac_CF(mesh(*point))).reshape(3, 3)
        numeric = np.empty((3, 3), complex)
        for j in range(3):
            hi, lo = np.array(point), np.array(point)
            hi[j] += step
            lo[j] -= step
            numeric[:, j] = (mapped(hi) - mapped(lo)) / (2 * step)
        # central differences: truncation ~ step^2 b t / d^3 ~ 1e-10 (depth d >= 0.04)
        # and rounding ~ 1e-16 |x~| / step ~ 1e-10
        assert np.allclose(jac, numeric, rtol=1e-7, atol=1e-7)


def test_pml_arguments_are_checked():
    with pytest.raises(ValueError, match="strength"):
        acoustics.radial_pml(0.1, 0.02, strength=-1.0)
    with pytest.raises(ValueError, match="profile"):
        acoustics.radial_pml(0.1, 0.02, profile="quadratic")
    with pytest.raises(ValueError, match="geometry.frame"):
        acoustics.screen_faces("round")   # circle is a frame since the axisymmetric engine
    with pytest.raises(ValueError, match="screens"):
        acoustics.pressure_space(None, 2, "membrane|rim")
    assert acoustics.open_plane_faces(acoustics.screen_faces("baffle")) == "aperture"
    assert acoustics.open_plane_faces(acoustics.screen_faces("square")) == "aperture|pml_plane"


def _pulsating_sphere_octant(source_radius, domain_radius, pml_thickness, air_size, source_size):
    """One octant of air between a sphere and R, plus the PML shell (symmetry planes Neumann).

    Region names follow the project's geometry (``air_upper``, ``pml_upper``,
    ``outer``) so the package's forms apply unchanged; the source sphere is
    ``source``, the three cut planes ``symmetry``.
    """
    from netgen.occ import Box, Glue, OCCGeometry, Pnt, Sphere

    octant = Box(Pnt(0, 0, 0), Pnt(1, 1, 1))
    source = Sphere(Pnt(0, 0, 0), source_radius)
    ball = Sphere(Pnt(0, 0, 0), domain_radius)
    shell = Sphere(Pnt(0, 0, 0), domain_radius + pml_thickness) - ball
    air = (ball - source) * octant
    air.mat("air_upper")
    pml_shell = shell * octant
    pml_shell.mat("pml_upper")
    shape = Glue([air, pml_shell])
    for face in shape.faces:
        lo, hi = face.bounding_box
        if min(h - l for h, l in zip(hi, lo)) < 1e-5 * domain_radius:
            face.name = "symmetry"
            continue
        extent = max(abs(v) for v in (*lo, *hi))
        if extent < 1.01 * source_radius:
            face.name = "source"
            face.maxh = source_size
        elif extent < 1.01 * domain_radius:
            face.name = "interface"
        else:
            face.name = "outer"
    ngmesh = OCCGeometry(shape).GenerateMesh(maxh=air_size, grading=0.3)
    mesh = ngsolve.Mesh(ngmesh)
    mesh.Curve(3)
    return mesh


@pytest.fixture(scope="module")
def pulsating_sphere():
    """Sphere of radius a = r_o in air to R = 3.5 a with a 0.5 a PML: the study's proportions."""
    a = OUTER_RADIUS
    R, t = 3.5 * a, 0.5 * a
    mesh = _pulsating_sphere_octant(a, R, t, air_size=0.02, source_size=0.01)
    acoustics.set_pml(mesh, R, t)
    space = ngsolve.H1(mesh, order=PRESSURE_ORDER, complex=True, dirichlet=acoustics.OUTER)
    acoustics.set_order_in(space, mesh, acoustics.PML_REGIONS,
                           PRESSURE_ORDER + acoustics.PML_EXTRA_ORDER)
    return mesh, space, a, R


@pytest.mark.parametrize("frequency", FREQUENCIES)
def test_pulsating_sphere_impedance_and_field(pulsating_sphere, frequency):
    """Monopole: Z = rho c (-ika)/(1 - ika), p(r) = Z v0 (a/r) e^{ik(r-a)} (e^{-i omega t}).

    The monopole is the hardest case for a PML in a thin shell (its near field
    carries the whole volume flux), so it bounds the membrane's case.
    """
    mesh, space, a, R = pulsating_sphere
    v0 = 1.0                                     # normal velocity of the sphere [m/s]
    k = 2 * math.pi * frequency / SOUND_SPEED

    def load(test, omega):   # -omega^2 c(u, p'), one-sided (air on the + side of n = e_r)
        return -omega**2 * (1j * v0 / omega) * test * ngsolve.ds("source")

    p = _solve(mesh, space, frequency, load)
    area = ngsolve.Integrate(1, mesh, ngsolve.BND, definedon=mesh.Boundaries("source"))
    impedance = ngsolve.Integrate(p, mesh, ngsolve.BND, definedon=mesh.Boundaries("source")) / area / v0
    exact = DENSITY * SOUND_SPEED * (-1j * k * a) / (1 - 1j * k * a)
    # 1 %: the closed form is exact for this geometry, so only discretisation
    # and PML reflection are left.  Measured 0.4 / 0.1 / 0.2 % at 200 / 500 /
    # 1000 Hz (PML reflection dominates at 200 Hz: kR = 0.45).
    assert abs(impedance - exact) / abs(exact) < 0.01
    assert impedance.imag < 0          # mass-like reactance in e^{-i omega t}: outgoing wave
    directions = np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1), (1, 2, 3), (3, 1, 0.5)])
    directions = directions / np.linalg.norm(directions, axis=1)[:, None]
    for radius in (1.5 * a, 2.5 * a, 3.4 * a):
        field_exact = exact * v0 * a / radius * np.exp(1j * k * (radius - a))
        worst = max(abs(p(mesh(*(radius * d))) - field_exact) for d in directions)
        # 1 % where the PML reflection is small (kR >= 1.1 at 500 Hz); at 200 Hz
        # (kR = 0.45) the reflected part is a standing, ~uniform field while
        # the outgoing one falls as 1/r, so the relative error grows with r:
        # measured 0.7 / 1.0 / 1.3 % at 1.5 / 2.5 / 3.4 a.  Allow 2 % there.
        tolerance = 0.02 if k * R < 1 else 0.01
        assert worst / abs(field_exact) < tolerance, (radius, worst / abs(field_exact))


# ----------------------------------------------------------- jump space, piston

def _air_mesh(mesh_cache, frame, domain_factor, membrane_size=0.009, symmetry="quarter"):
    """Project mesh with air (coarse: 9 mm on the membrane, 0.5 r_o in the air).

    It is the default quadrant (mesh.symmetry: quarter): a piston is even about
    both mirror planes, whose natural condition dp/dn = 0 is then exact.
    """
    study = parse_study({"geometry": {"frame": frame},
                         "air": {"enabled": True, "domain_radius": domain_factor * OUTER_RADIUS},
                         "mesh": {"membrane_size": membrane_size, "symmetry": symmetry}})
    spec = GeometrySpec.from_study(study)
    mesh = load_mesh(spec, curve_order=3, cache_dir=mesh_cache)
    acoustics.set_pml(mesh, study.air.domain_radius, study.air.pml_thickness)
    space = acoustics.pressure_space(mesh, PRESSURE_ORDER, acoustics.screen_faces(frame))
    return mesh, space


PISTON = "membrane|disc"     # the rigid piston of radius r_o: membrane and disc faces together


def _piston_response(mesh, space, frequency, v0=1.0):
    """Force on the upper face / v0 [N s/m], and antisymmetry of the face pressures."""
    def load(test, omega):
        return -omega**2 * acoustics.screen_coupling(test, 1j * v0 / omega, PISTON)

    solution = _solve(mesh, space, frequency, load)
    p, q = solution.components
    upper_face, lower_face = p, p + q            # acoustics.upper_/lower_pressure on the faces

    copies = Symmetry.of_mesh(mesh).copies      # the default air mesh is one quadrant

    def integral(cf):
        return copies * ngsolve.Integrate(cf, mesh, ngsolve.BND, definedon=mesh.Boundaries(PISTON))

    impedance = integral(upper_face) / v0
    mismatch = math.sqrt(abs(integral(ngsolve.Norm(upper_face + lower_face) ** 2)))
    size = math.sqrt(abs(integral(ngsolve.Norm(upper_face) ** 2)))
    return impedance, mismatch / size


def _piston_closed_form(frequency):
    """Baffled piston Z = rho c S [1 - J1(2ka)/ka - i H1(2ka)/ka] (e^{-i omega t}) [N s/m]."""
    k = 2 * math.pi * frequency / SOUND_SPEED
    ka = k * OUTER_RADIUS
    area = math.pi * OUTER_RADIUS**2
    return DENSITY * SOUND_SPEED * area * (1 - j1(2 * ka) / ka - 1j * struve(1, 2 * ka) / ka)


@pytest.fixture(scope="module")
def baffle(mesh_cache):
    return _air_mesh(mesh_cache, "baffle", 3.5)


@pytest.mark.parametrize("frequency", FREQUENCIES)
def test_baffled_piston_impedance(baffle, frequency):
    """Jump space on the real geometry: membrane + disc as a rigid piston in the baffle.

    The baffle continues through the PML (``pml_plane`` is a screen), so the
    model is the infinite baffle of the closed form; what is left is
    discretisation and PML reflection.
    """
    mesh, space = baffle
    impedance, antisymmetry = _piston_response(mesh, space, frequency)
    exact = _piston_closed_form(frequency)
    # Reactance = radiation mass, the source of the membrane's added mass:
    # 1 %, which moves a coupled frequency with 30-45 % added mass by < 0.2 %,
    # inside the 0.5 % the eigen step aims at.  Measured -0.54 / -0.32 / -0.28 %
    # (9 mm membrane mesh; 0.3 / 0.08 / 0.02 % at 6 mm): discretisation of the
    # pressure near the piston edge.
    assert abs(impedance.imag - exact.imag) / abs(exact.imag) < 0.01
    assert impedance.imag < 0
    # Resistance = radiated power, a far-field quantity.  At 200 Hz it is 8 % of |Z|
    # and the PML at kR = 0.45 leaves 2.0 % on it (6 mm mesh: 2.0 % at R = 3.5 r_o,
    # 0.4 % at 5 r_o); measured on this 9 mm mesh +2.03 / +0.28 / +0.07 % at
    # 200 / 500 / 1000 Hz, tested at about twice that.
    tolerance = {200.0: 0.04, 500.0: 6e-3, 1000.0: 2e-3}[frequency]
    assert abs(impedance.real - exact.real) / exact.real < tolerance
    # p- = -p+ on the piston by the z -> -z symmetry of geometry and load; the
    # mesh is not mirror-symmetric, so only up to discretisation (measured 2.2e-3).
    assert antisymmetry < 5e-3


def test_jump_lives_on_screens_only(baffle, mesh_cache):
    """q has DOFs on the screen faces only; with a square frame it vanishes on the aperture."""
    mesh, space = baffle
    jump_space = space.components[1]
    assert 0 < jump_space.ndof < space.components[0].ndof / 5
    square_mesh, square_space = _air_mesh(mesh_cache, "square", 3.5)
    q = ngsolve.GridFunction(square_space.components[1])
    q.vec.FV().NumPy()[:] = np.random.default_rng(0).standard_normal(q.space.ndof)
    on_aperture = ngsolve.Integrate(ngsolve.Norm(q) ** 2, square_mesh, ngsolve.BND,
                                    definedon=square_mesh.Boundaries("aperture"))
    on_frame = ngsolve.Integrate(ngsolve.Norm(q) ** 2, square_mesh, ngsolve.BND,
                                 definedon=square_mesh.Boundaries("frame"))
    assert abs(on_aperture) < 1e-12 * abs(on_frame) and abs(on_frame) > 0


@pytest.mark.slow
@pytest.mark.parametrize("frame", ["baffle", "square"])
def test_piston_independent_of_air_radius(mesh_cache, frame):
    """Radiation impedance barely moves when the air sphere grows from 3.5 to 5 r_o."""
    results = {}
    for factor in (3.5, 5.0):
        mesh, space = _air_mesh(mesh_cache, frame, factor)
        results[factor] = [_piston_response(mesh, space, f)[0] for f in FREQUENCIES]
    for small, large in zip(results[3.5], results[5.0]):
        # 1 % of |Z|, the reactance tolerance of the closed-form test.  Measured
        # (9 mm mesh) baffle 0.03-0.15 %, square 0.2-0.3 %.  The square frame's
        # resistance is a dipole's, (ka)^4-small at 200 Hz: only |Z| is meaningful.
        assert abs(small - large) / abs(large) < 0.01
        if frame == "baffle":   # resistance: 5 %, as in the closed-form test
            assert abs(small.real - large.real) / abs(large.real) < 0.05


# ------------------------------------------------- coupled sign check (eq. A3)

@pytest.fixture(scope="module")
def whole_baffle(mesh_cache):
    """The whole air (no mirror planes): for tests that build their own membrane space."""
    return _air_mesh(mesh_cache, "baffle", 3.5, symmetry="none")


def test_air_loading_lowers_flat_membrane_frequencies(whole_baffle):
    """Flat membrane (w only, tension T) in the baffle: every wet frequency below its dry one.

    Checks the sign of both coupling rows of eq. (A3): with a wrong sign the
    added mass ``C^T K_a^-1 C`` turns negative and the frequencies rise.
    """
    import scipy.sparse.linalg as sla

    mesh, pressure = whole_baffle
    tension = 25.7                                   # [N/m], flat G1 at 2 kV (brief)
    areal_density = 1490 * 100e-6 / 1.2**2           # rho0 h0 / lambda_p^2 [kg/m^2]
    membrane = ngsolve.Compress(ngsolve.H1(
        mesh, order=2, complex=True, definedon=mesh.Boundaries("membrane"),
        dirichlet_bbnd="outer_rim|inner_rim"))
    # PML order 2 (not 3): a sign check needs no accurate radiation, and it halves the cost
    pressure = acoustics.pressure_space(mesh, PRESSURE_ORDER, acoustics.screen_faces("baffle"),
                                        pml_order=PRESSURE_ORDER)
    space = ngsolve.FESpace([membrane, *pressure.components])
    ds = ngsolve.ds("membrane")

    def membrane_forms(w, w_test):     # k_s, m_s of the flat tensioned membrane
        return (tension * ngsolve.grad(w).Trace() * ngsolve.grad(w_test).Trace() * ds,
                areal_density * w * w_test * ds)

    (w, p, q), (w_test, p_test, q_test) = space.TnT()
    a, b = acoustics.coupled_forms((p, q), (p_test, q_test), w, w_test,
                                   *membrane_forms(w, w_test), DENSITY, SOUND_SPEED)

    def eigenfrequencies(space, a, b, shift_hz, count):
        """``count`` eigenfrequencies [Hz] nearest ``shift_hz``: shift-invert, scipy eigs."""
        free = np.flatnonzero(np.array(list(space.FreeDofs())))
        shift = complex((2 * math.pi * shift_hz) ** 2)
        mat_b = ngsolve.BilinearForm(b).Assemble().mat
        inverse = ngsolve.BilinearForm(a - shift * b).Assemble().mat.Inverse(
            space.FreeDofs(), inverse="umfpack")
        x, y = mat_b.CreateColVector(), mat_b.CreateColVector()

        def apply(vector):
            x[:] = 0
            x.FV().NumPy()[free] = vector.ravel()
            y.data = mat_b * x
            x.data = inverse * y
            return x.FV().NumPy()[free].copy()

        op = sla.LinearOperator((free.size, free.size), matvec=apply, dtype=complex)
        theta = sla.eigs(op, k=count, which="LM", return_eigenvectors=False, tol=1e-8)
        omega = np.sqrt(shift + 1 / theta)
        return np.sort_complex(omega / (2 * math.pi))

    dry = eigenfrequencies(membrane, *membrane_forms(*membrane.TnT()), 300.0, 5).real
    # (0,1), (1,1) pair, (2,1) pair of the annulus, dry at 425-470 Hz on this mesh;
    # shift where the wet ones are expected (added mass of tens of %)
    wet = eigenfrequencies(space, a, b, 0.85 * dry[0], 5)
    structural = wet[abs(wet.imag) < 0.05 * wet.real]     # drop strongly damped PML modes
    assert structural.size >= 5, wet
    assert np.all(structural.real[:5] < dry[:5]), (structural, dry)   # sorted wet below sorted dry
    assert np.all(structural.imag <= 1e-9 * structural.real)          # radiation only damps
    added_mass_ratio = (dry[0] / structural.real[0]) ** 2 - 1         # (0,1)
    # positive; tens of % (flat membrane: 46 % in the baffle, 31 % in the square frame)
    assert 0.1 < added_mass_ratio < 1.0, added_mass_ratio
