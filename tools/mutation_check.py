"""Mutation check of the physics: does the fast suite catch small deliberate bugs?

A tool, not a CI gate (pytest does not collect this file: its name does not start with
``test_``).  Each mutation below is an exact source-text replacement in ``copdea_fem/``
-- a constant, a factor of 2 or 4, a sign, a missing energy term, the PML, the
coupling, the post-processing.  For each one the repository (package, tests, studies,
the mesh cache, pyproject.toml, README.md) is copied to a temporary directory, the replacement is
made there -- never in the working tree -- and the fast suite is run against the copy in
a subprocess (``python -m pytest -x -q``, working directory and PYTHONPATH the copy),
stopping at the first failure.  A mutation is *killed* when the suite fails, *survived*
when it passes.  Every mutation's text must occur exactly once in its file: when the
code has moved, the check stops before running anything and names the mutation.

Run from the repository root::

    python tools/mutation_check.py               # all mutations (tens of minutes on 2 cores)
    python tools/mutation_check.py --list        # what would be planted
    python tools/mutation_check.py --only air_density_x1.3 modal_mass_doubled
    python tools/mutation_check.py --baseline    # first the unmutated copy (must pass)

Exit status 0 when every mutation is killed, 1 when one survived, 2 on bad use (a
mutation's text not found exactly once, an unknown name).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COPIED = ("copdea_fem", "tests", "studies", "meshes", "pyproject.toml", "README.md")
#: The test files that kill most physics mutations, run first (the rest follow in
#: name order): with -x a killed mutation then costs seconds to a minute, not the suite.
FIRST = ("tests/fe/test_vent_helmholtz.py", "tests/test_mac.py",
         "tests/fe/test_materials.py", "tests/fe/test_damping.py", "tests/fe/test_coupled_references.py",
         "tests/fe/test_axisymmetric.py",
         "tests/fe/test_acoustics.py", "tests/fe/test_coupled.py", "tests/fe/test_symmetry.py",
         "tests/fe/test_dry_modes.py", "tests/fe/test_prestress.py", "tests/test_damping_fit.py",
         "tests/forced_response/test_response_reduced.py", "tests/forced_response/test_response_engines.py")


@dataclass(frozen=True)
class Mutation:
    name: str
    path: str          # relative to the repository root
    old: str
    new: str
    what: str


MUTATIONS = (
    # --- the five that survived the suite before issue 16 --------------------------------
    Mutation("damping_ratio_doubled", "copdea_fem/fe/modes.py",
             "return float(-self.freq_im_hz / magnitude) if magnitude > 0 else 0.0",
             "return float(-2 * self.freq_im_hz / magnitude) if magnitude > 0 else 0.0",
             "mode post-processing: damping ratio twice -Im f / |f|"),
    Mutation("air_density_x1.3", "copdea_fem/fe/coupled.py",
             'density, sound_speed = air.density, air.sound_speed',
             'density, sound_speed = 1.3 * air.density, air.sound_speed',
             "coupled assembly: air density 1.3 rho_a"),
    Mutation("quadrant_disc_area_without_4", "copdea_fem/fe/coupled.py",
             "disc_area = state.symmetry.copies * ngs.Integrate(",
             "disc_area = ngs.Integrate(",
             "coupled assembly: the quadrant's disc area not times 4 (disc mass, spring x4)"),
    Mutation("modal_mass_doubled", "copdea_fem/fe/modes.py",
             "modal_mass=copies * total * scale**2,",
             "modal_mass=2 * copies * total * scale**2,",
             "mode post-processing: modal mass doubled"),
    Mutation("air_kinetic_energy_halved", "copdea_fem/fe/modes.py",
             "kinetic_air = float(np.real(np.vdot(p, coupled.air_kinetic @ p))) / magnitude",
             "kinetic_air = float(np.real(np.vdot(p, coupled.air_kinetic @ p))) / (2 * magnitude)",
             "membrane-energy fraction: air kinetic energy halved"),
    # --- the two caught by a single loose bound before issue 16 --------------------------
    Mutation("air_mesh_not_following_membrane", "copdea_fem/fe/coupled.py",
             "                                   cavity_depth=depth if closed else None)",
             "                                   cavity_depth=depth if closed else None)\n"
             "    motion.vec[:] = 0",
             "ALE: the air mesh stays flat under the prestressed membrane"),
    Mutation("pml_on_upper_half_only", "copdea_fem/fe/acoustics.py",
             "mesh.SetPML(stretch, PML_REGIONS)",
             'mesh.SetPML(stretch, "pml_upper")',
             "PML: only the upper shell stretched"),
    # --- PML and air ---------------------------------------------------------------------
    Mutation("pml_stretch_sign", "copdea_fem/fe/acoustics.py",
             "r_stretched = r + 1j * beta",
             "r_stretched = r - 1j * beta",
             "PML: stretch of the wrong sign (absorbs incoming, not outgoing waves)"),
    Mutation("pml_jacobian_half_radial_derivative", "copdea_fem/fe/acoustics.py",
             "dbeta_dr = strength * t / depth_left",
             "dbeta_dr = 0.5 * strength * t / depth_left",
             "PML: Jacobian inconsistent with the map"),
    Mutation("sound_speed_x1.2", "copdea_fem/fe/acoustics.py",
             "compressibility = 1.0 / (density * sound_speed**2)",
             "compressibility = 1.0 / (density * (1.2 * sound_speed)**2)",
             "air: compressibility of a 20 % faster sound speed"),
    Mutation("lower_air_stiffness_without_jump", "copdea_fem/fe/acoustics.py",
             "lambda value, test: (1.0 / density) * grad(value) * grad(test),",
             "lambda value, test: (1.0 / density) * grad(pressure[0]) * grad(test),",
             "air: lower half's stiffness misses the jump field q"),
    Mutation("lower_air_mass_without_jump", "copdea_fem/fe/acoustics.py",
             "lambda value, test: compressibility * value * test,",
             "lambda value, test: compressibility * pressure[0] * pressure_test[0],",
             "air: lower half's compressibility misses the jump field q"),
    Mutation("baffle_stops_at_the_pml", "copdea_fem/fe/acoustics.py",
             'return "membrane|disc|frame|pml_plane"',
             'return "membrane|disc|frame"',
             "air: the baffle does not continue through the PML (an edge at r = R)"),
    # --- coupling ------------------------------------------------------------------------
    Mutation("air_row_coupling_sign", "copdea_fem/fe/acoustics.py",
             "acceleration = (-1.0) * screen_coupling(pressure_test, normal_displacement,",
             "acceleration = (1.0) * screen_coupling(pressure_test, normal_displacement,",
             "coupling: the membrane's acceleration enters the air with the wrong sign"),
    Mutation("membrane_traction_halved", "copdea_fem/fe/acoustics.py",
             "a = traction + air_stiffness(pressure, pressure_test,",
             "a = 0.5 * traction + air_stiffness(pressure, pressure_test,",
             "coupling: the air pushes the membrane with half the pressure jump"),
    Mutation("coupled_membrane_mass_halved", "copdea_fem/fe/coupled.py",
             "areal_density(material) * u * v * measure, density, sound_speed,",
             "0.5 * areal_density(material) * u * v * measure, density, sound_speed,",
             "coupled assembly: membrane mass halved"),
    Mutation("no_air_force_on_the_disc", "copdea_fem/fe/coupled.py",
             "stiffness += disc_traction",
             "stiffness += 0 * disc_traction",
             "coupling: the disc on its spring feels no air pressure"),
    # --- membrane energy, mass, disc -----------------------------------------------------
    Mutation("electrostatic_coenergy_sign", "copdea_fem/fe/materials.py",
             "return -0.5 * self.permittivity * self.nominal_field_sq(voltage) * det_c",
             "return 0.5 * self.permittivity * self.nominal_field_sq(voltage) * det_c",
             "energy: Maxwell stress stiffens instead of softening"),
    Mutation("mooney_rivlin_without_c20", "copdea_fem/fe/materials.py",
             "return self.c10 * (i1 - 3) + self.c20 * (i1 - 3) ** 2 + self.c01 * (i_inv - 3)",
             "return self.c10 * (i1 - 3) + self.c01 * (i_inv - 3)",
             "energy: the c20 term of eq. (20) missing"),
    Mutation("membrane_mass_doubled", "copdea_fem/fe/linearise.py",
             "mass = ngs.BilinearForm(areal_density(material) * u * v * on_membrane,",
             "mass = ngs.BilinearForm(2 * areal_density(material) * u * v * on_membrane,",
             "dry operators: membrane mass doubled"),
    Mutation("spring_mass_half_not_third", "copdea_fem/fe/linearise.py",
             'disc_mass = (study.disc.mass + disc_point_mass(study) + spring.mass / 3) / ',
             'disc_mass = (study.disc.mass + disc_point_mass(study) + spring.mass / 2) / ',
             "disc: M_d + M_s/2 instead of Rayleigh's M_s/3"),
    Mutation("quadrant_spring_not_divided", "copdea_fem/fe/linearise.py",
             'spring.stiffness / symmetry.copies)',
             'spring.stiffness)',
             "disc: the quadrant's pencil carries the whole spring"),
    Mutation("quadrant_masses_not_times_4", "copdea_fem/fe/modes.py",
             "copies = state.symmetry.copies      # a quadrant's masses are a quarter",
             "copies = 1      # a quadrant's masses are a quarter",
             "mode post-processing: a quadrant's modal mass reported for the device"),
    Mutation("disc_fraction_over_membrane_energy", "copdea_fem/fe/modes.py",
             "disc_fraction = disc_energy / total",
             "disc_fraction = disc_energy / membrane_energy",
             "mode post-processing: disc share over the membrane's energy, not the total"),
    Mutation("quadrant_disc_force_not_times_4", "copdea_fem/fe/prestress.py",
             "return self.symmetry.copies * float(ngs.InnerProduct(self.residual, "
             "self.disc_lift.vec))",
             "return float(ngs.InnerProduct(self.residual, self.disc_lift.vec))",
             "prestress: a quadrant's disc force reported for the device"),
    # --- post-processing -----------------------------------------------------------------
    Mutation("added_mass_ratio_not_squared", "copdea_fem/output/tables.py",
             '"added_mass_ratio": (dry / mode.freq_hz) ** 2 - 1 if mode.freq_hz > 0 else 0.0,',
             '"added_mass_ratio": (dry / mode.freq_hz) - 1 if mode.freq_hz > 0 else 0.0,',
             "modes.csv: added-mass ratio f_dry/f - 1 instead of (f_dry/f)^2 - 1"),
    Mutation("damping_ratio_sign", "copdea_fem/fe/modes.py",
             "return float(-self.freq_im_hz / magnitude) if magnitude > 0 else 0.0",
             "return float(self.freq_im_hz / magnitude) if magnitude > 0 else 0.0",
             "mode post-processing: damping ratio of the wrong sign (e^{-i omega t})"),
    # --- the axisymmetric engine ------------------------------------------------------------
    Mutation("axisymmetric_hoop_term_m_not_squared", "copdea_fem/fe/axisymmetric/operators.py",
             'air_stiffness = theta * (blocks["gradient"] + m**2 * blocks["hoop"])',
             'air_stiffness = theta * (blocks["gradient"] + m * blocks["hoop"])',
             "meridian air: the (1/r d/dtheta)^2 term of order m with m instead of m^2"),
    Mutation("axisymmetric_pml_hoop_not_stretched", "copdea_fem/fe/axisymmetric/air.py",
             "hoop_part = hoop_part + p * p_test / (s * r) ** 2 * volume / density * pml",
             "hoop_part = hoop_part + p * p_test / r ** 2 * volume / density * pml",
             "meridian PML: the hoop direction not stretched (1/r~ = 1/(s r))"),
    Mutation("axisymmetric_pml_volume_without_hoop", "copdea_fem/fe/axisymmetric/air.py",
             "volume = s * (s * derivative) * r",
             "volume = (s * derivative) * r",
             "meridian PML: volume element det(J2) r without the hoop stretch s"),
    Mutation("axisymmetric_coupling_without_radius", "copdea_fem/fe/axisymmetric/operators.py",
             'coupling += (-pressure_test[1]) * u_normal * ngs.x * ngs.ds("membrane",',
             'coupling += (-pressure_test[1]) * u_normal * ngs.ds("membrane",',
             "meridian coupling: the screen integral without its r weight"),
    Mutation("axisymmetric_harmonic_gradient_sign", "copdea_fem/fe/axisymmetric/membrane.py",
             "sin_part = cf_entries((0, -(m * a + b) / R, 0, db, 0, 0, 0, -m * c / R, 0), dims=(3, 3))",
             "sin_part = cf_entries((0, -(m * a - b) / R, 0, db, 0, 0, 0, -m * c / R, 0), dims=(3, 3))",
             "order-m membrane: (U_r,theta - U_theta)/R with the wrong sign of U_theta"),
    Mutation("axisymmetric_hoop_strain_of_prestress", "copdea_fem/fe/axisymmetric/membrane.py",
             "return cf_entries((derivative[0, 0], 0, 0, 0, u[0] / radius(), 0, derivative[1, 0], 0, 0),",
             "return cf_entries((derivative[0, 0], 0, 0, 0, 0 * u[0] / radius(), 0, derivative[1, 0], 0, 0),",
             "axisymmetric prestress: the hoop strain u_r / R missing"),
    Mutation("axisymmetric_theta_integral_of_m0", "copdea_fem/fe/axisymmetric/meridian.py",
             "return 2 * math.pi if m == 0 else math.pi",
             "return math.pi",
             "axisymmetric: int cos^2(0 theta) d theta = pi instead of 2 pi (masses of m = 0)"),
    # --- the damped eigen step (issue 23) -------------------------------------------------
    Mutation("damping_sign_of_c", "copdea_fem/fe/linearise.py",
             'damping = (alpha * mass + beta * stiffness).tocsr() if (alpha or beta) else None',
             'damping = (-alpha * mass - beta * stiffness).tocsr() if (alpha or beta) else None',
             "Rayleigh damping C with the wrong sign (modes grow)"),
    Mutation("damping_beta_on_mass", "copdea_fem/fe/linearise.py",
             'damping = (alpha * mass + beta * stiffness).tocsr() if (alpha or beta) else None',
             'damping = (alpha * mass + beta * mass).tocsr() if (alpha or beta) else None',
             "Rayleigh damping: beta multiplies the mass instead of the stiffness"),
    Mutation("prony_ratio_ignored", "copdea_fem/fe/linearise.py",
             'relaxation = [(term.modulus_ratio * tangent, term.relaxation_time)',
             'relaxation = [(tangent, term.relaxation_time)',
             "Prony series: every branch with the full material tangent (ratio ignored)"),
    Mutation("prony_internal_variable_sign", "copdea_fem/fe/eigen/damped.py",
             "= (1j * x[support] - r3[j]) / (1j + sigma * tau)",
             "= (1j * x[support] + r3[j]) / (1j + sigma * tau)",
             "damped shift-invert: the Prony internal variable's back-substitution sign"),
    # --- calibrate-damping --fit rayleigh|prony (issue 23) -----------------------------------
    Mutation("damping_fit_radiation_kept", "copdea_fem/damping_fit.py",
             "target = measured.damping_ratio - radiation",
             "target = measured.damping_ratio - 0 * radiation",
             "damping fit: the FE's radiation damping not subtracted from the measured one"),
    Mutation("damping_fit_rayleigh_beta_doubled", "copdea_fem/damping_fit.py",
             "return alpha / (2 * omega) + beta * omega / 2",
             "return alpha / (2 * omega) + beta * omega",
             "damping fit: Rayleigh zeta = alpha / (2 omega) + beta omega (half missing)"),
    Mutation("damping_fit_prony_loss_peak", "copdea_fem/damping_fit.py",
             "return modulus_ratio * share * wt / (2 * (1 + wt**2))",
             "return modulus_ratio * share * wt / (2 * (1 + wt))",
             "damping fit: the Prony loss peak omega tau / (1 + omega tau) (a square missing)"),
    Mutation("axisymmetric_pair_missing", "copdea_fem/fe/axisymmetric/modes.py",
             'if mode.m > 0 and (mode.kind != AIR or mode.cavity_orders):',
             'if mode.m > 1 and (mode.kind != AIR or mode.cavity_orders):',
             "axisymmetric modes: the m = 1 modes reported without their sin twin"),
    # --- issue 23: the reduced-basis forced response ---------------------------------------
    Mutation("reduced_shift_dropped", "copdea_fem/forced_response/reduced_basis.py",
             "            krylov, count = builder.krylov(2 * math.pi * f, steps, scale)",
             "            krylov, count = builder.krylov(2 * math.pi * f, steps, scale)\n"
             "            if f == plan[-1] and len(plan) > 1:\n                continue",
             "reduced basis: the last shift of a plan left out"),
    Mutation("reduced_rayleigh_sign", "copdea_fem/forced_response/reduced_basis.py",
             'pieces.append((terms.damping, lambda w: -1j * w, "C"))',
             'pieces.append((terms.damping, lambda w: 1j * w, "C"))',
             "reduced basis: the sign of the Rayleigh term -i omega C"),
    Mutation("reduced_prony_ignored", "copdea_fem/forced_response/reduced_basis.py",
             "lambda w, tau=tau: -1j * w * tau / (1 - 1j * w * tau)",
             "lambda w, tau=tau: 0.0 * w",
             "reduced basis: the Prony branches left out of the projection"),
    Mutation("reduced_forcing_row", "copdea_fem/forced_response/reduced_basis.py",
             "rhs[n:2 * n] = self.force", "rhs[:n] = self.force",
             "reduced basis: the forcing in the wrong row of the linearisation"),
    # --- the 3-D forced response pinned to the axisymmetric one ---------------------------
    Mutation("quadrant_forcing_halved", "copdea_fem/fe/quadrant/forced.py",
             "    return reduce_vector_3d(force, operators), balance",
             "    return reduce_vector_3d(0.5 * force, operators), balance",
             "3-D forced response: the voltage forcing halved (the engine's own use of the "
             "shared forcing)"),
    Mutation("shared_forcing_halved", "copdea_fem/fe/forced/harmonic.py",
             "    force = -2.0 * (at_bias - at_zero) / voltage_b",
             "    force = -1.0 * (at_bias - at_zero) / voltage_b",
             "forced response: the shared voltage forcing halved (both engines)"),
    Mutation("green_time_sign", "copdea_fem/fe/forced/radiation.py",
             "        g = np.exp(1j * wavenumber * d) / (4 * np.pi * d)",
             "        g = np.exp(-1j * wavenumber * d) / (4 * np.pi * d)",
             "far field: the shared Green's function with the e^{+i omega t} sign (both engines)"),
    Mutation("local_cluster_one_worker", "copdea_fem/parallel.py",
             "    count = local_workers(workers)\n",
             "    count = local_workers(workers) if workers is not None else 1\n",
             "Dask: the default local cluster given one worker"),
    Mutation("uff_164_factor_inverted", "copdea_fem/measured/uff_units.py",
             'return 1.0 / (units["length"] ** length * units["force"] ** force)',
             'return units["length"] ** length * units["force"] ** force',
             "UFF reading: dataset 164's factor multiplied instead of divided (a 58 whose "
             "label names no unit)"),
    Mutation("uff_negative_direction_positive", "copdea_fem/measured/uff.py",
             "direction[abs(code) - 1] = np.sign(code)",
             "direction[abs(code) - 1] = 1.0",
             "UFF reading: a negative measuring direction (rsp_dir -3) read as positive"),
    Mutation("stable_pole_damping_absolute", "copdea_fem/vibrometer/identification.py",
             "damping_ok = abs(damping[i] - last_d) / last_d < d_tol",
             "damping_ok = abs(damping[i] - last_d) < d_tol",
             "stabilisation diagram: the damping's stability check absolute, not relative"),
    Mutation("mac_without_conjugate", "copdea_fem/mac.py",
             "    cross = a.conj().T @ weighted_b",
             "    cross = a.T @ weighted_b",
             "MAC: the complex conjugate of the first shape left out (measured shapes, the "
             "sweeps' tracking)"),
    Mutation("enclosure_depth_linear_grid", "copdea_fem/diagnosis/effects.py",
             "                          *ENCLOSURE_DEPTH_RATIO, True,",
             "                          *ENCLOSURE_DEPTH_RATIO, False,",
             "diagnosis: the enclosure effect's depth searched on a linear grid"),
    Mutation("vent_radius_halved_axisymmetric", "copdea_fem/fe/axisymmetric/meridian.py",
             "vent_radius=vent if enclosed else 0.0,",
             "vent_radius=0.5 * vent if enclosed else 0.0,",
             "axisymmetric mesh: the enclosure's vent radius halved"),
)


def check_mutations(mutations, root: Path = ROOT) -> None:
    """Every mutation's text occurs exactly once in its file (else ValueError, named)."""
    problems = []
    for mutation in mutations:
        source = (root / mutation.path).read_text()
        count = source.count(mutation.old)
        if count != 1:
            problems.append(f"{mutation.name}: {count} matches of {mutation.old!r} in "
                            f"{mutation.path} (exactly 1 allowed; the code moved?)")
    if problems:
        raise ValueError("\n".join(problems))


def copy_repository(target: Path) -> None:
    for name in COPIED:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, target / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache"))
        elif source.exists():
            shutil.copy2(source, target / name)


def suite_files(root: Path) -> list[str]:
    """FIRST, then every other test file in name order (explicit files: no duplicates)."""
    others = sorted(str(path.relative_to(root)) for path in (root / "tests").rglob("test_*.py"))
    return [name for name in FIRST if (root / name).exists()] + [
        name for name in others if name not in FIRST]


def run_suite(root: Path, timeout: float) -> tuple[str, str, float]:
    """Fast suite against the copy at ``root``: (status, first failure, seconds)."""
    # a mutated FE has a new code fingerprint: the committed FE cache cannot judge it, so
    # the tests that read it are skipped, not failed (tests/diagnosis/conftest.py)
    env = dict(os.environ, PYTHONPATH=str(root), PYTHONDONTWRITEBYTECODE="1",
               COPDEA_FEM_FE_STALE="skip")
    check = subprocess.run([sys.executable, "-c", "import copdea_fem; print(copdea_fem.__file__)"],
                           cwd=root, env=env, capture_output=True, text=True)
    if not check.stdout.strip().startswith(str(root)):
        raise RuntimeError(f"the copy at {root} is not what Python imports: {check.stdout}"
                           f"{check.stderr}")
    start = time.perf_counter()
    command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-rfE",
               *suite_files(root)]
    try:
        result = subprocess.run(command, cwd=root, env=env, capture_output=True, text=True,
                                timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", "", time.perf_counter() - start
    seconds = time.perf_counter() - start
    failed = next((line for line in result.stdout.splitlines()
                   if line.startswith(("FAILED", "ERROR"))), "")
    if result.returncode == 0:
        return "survived", "", seconds
    if result.returncode in (1, 2):       # tests failed / collection interrupted
        return "killed", failed or result.stdout.strip().splitlines()[-1], seconds
    return "error", (result.stdout + result.stderr).strip()[-400:], seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    parser.add_argument("--only", nargs="+", metavar="NAME", help="run only these mutations")
    parser.add_argument("--baseline", action="store_true",
                        help="first run the unmutated copy (it must pass)")
    parser.add_argument("--timeout", type=float, default=1200.0,
                        help="seconds per suite run (default 1200)")
    args = parser.parse_args(argv)
    mutations = MUTATIONS
    if args.only:
        names = {mutation.name for mutation in MUTATIONS}
        unknown = sorted(set(args.only) - names)
        if unknown:
            print(f"unknown mutation(s): {', '.join(unknown)}; allowed: {', '.join(sorted(names))}",
                  file=sys.stderr)
            return 2
        mutations = tuple(mutation for mutation in MUTATIONS if mutation.name in args.only)
    try:
        check_mutations(mutations)
    except ValueError as error:
        print(error, file=sys.stderr)
        return 2
    if args.list:
        for mutation in mutations:
            print(f"{mutation.name:40s} {mutation.path:26s} {mutation.what}")
        return 0
    results = []
    if args.baseline:
        with tempfile.TemporaryDirectory(prefix="copdea-mutation-") as directory:
            copy_repository(Path(directory))
            status, failure, seconds = run_suite(Path(directory), args.timeout)
        print(f"baseline (no mutation): {'passes' if status == 'survived' else status} "
              f"({seconds:.0f} s) {failure}", flush=True)
        if status != "survived":
            return 1
    for number, mutation in enumerate(mutations, 1):
        with tempfile.TemporaryDirectory(prefix="copdea-mutation-") as directory:
            root = Path(directory)
            copy_repository(root)
            target = root / mutation.path
            source = target.read_text()
            target.write_text(source.replace(mutation.old, mutation.new, 1))
            status, failure, seconds = run_suite(root, args.timeout)
        results.append((mutation, status))
        print(f"[{number}/{len(mutations)}] {mutation.name}: {status} ({seconds:.0f} s) "
              f"{failure}", flush=True)
    killed = sum(status == "killed" for _, status in results)
    print(f"\n{killed} of {len(results)} mutations killed by the fast suite")
    for mutation, status in results:
        if status != "killed":
            print(f"  {status}: {mutation.name} ({mutation.path}: {mutation.what})")
    return 0 if killed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
