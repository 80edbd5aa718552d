"""The typed schema of ``study.yaml``: every key of every section with its SI unit,
default, bounds and description (:data:`SCHEMA`), and the README's table made from it.
"""

from __future__ import annotations

from copdea_fem.study.imperfections import read_point_masses, read_thickness_variation
from copdea_fem.study.keys import Key
from copdea_fem.study.segments import read_segments

G1 = "Table 1, G1"
ENGINES = ("auto", "3d", "axisymmetric")
AXISYMMETRIC_FRAMES = ("none", "baffle", "circle")
ENCLOSURES = ("none", "cylinder", "bowl", "box")
#: Enclosures the axisymmetric engine meshes (a box is 3-D only).
AXISYMMETRIC_ENCLOSURES = ("none", "cylinder", "bowl")
#: The enclosure's farthest point must lie within this share of air.domain_radius, so that
#: the outside air around it is meshed (frame none, circle, square).
ENCLOSURE_AIR_SHARE = 0.8
#: An enclosure's depth is at least this share of the outer radius, and its radii (vent,
#: disc, membrane, enclosure, circular frame) are equal or this share of r_o apart: Netgen
#: meshes the meridian at these limits in ~1 s, fails or hangs far below them.
ENCLOSURE_MIN_DEPTH, ENCLOSURE_MIN_GAP = 0.02, 1e-4
SCHEMA: dict[str, dict[str, Key]] = {
    "geometry": {
        "outer_radius": Key("m", 0.0355, f"outer radius r_o of the pre-stretched membrane ({G1})",
                            minimum=0, maximum=1.0, open_min=True),
        "inner_radius": Key("m", 0.017, "inner radius r_i = disc radius; 0 = full circular "
                            f"membrane, no disc ({G1}; G2: 12 mm)", minimum=0, maximum=1.0),
        "frame": Key(None, "square", "rigid reflecting frame in the membrane plane: square "
                     "(Sect. 5.1), baffle (infinite rigid plane), circle (a rigid ring plane "
                     "from r_o to geometry.frame_radius) or none", kind=str,
                     choices=("square", "baffle", "none", "circle")),
        "frame_side": Key("m", 0.080, "side of the square frame (Sect. 5.1)", minimum=0,
                          maximum=2.0, open_min=True),
        "frame_radius": Key("m", None, "outer radius of the circular frame (frame: circle)",
                            minimum=0, maximum=2.0, open_min=True,
                            derived="0.5 * geometry.frame_side"),
        "enclosure": Key(None, "none", "rigid closed back under the membrane, on z < 0 (away "
                         "from the disc's travel), its rim sealed to the membrane's rim: none "
                         "(open back), cylinder, bowl (a spherical cap, a drum's kettle) or box "
                         "(under the square frame, 3-D engine). The air inside (region "
                         "'cavity') is meshed and coupled like the outside air; with frame "
                         "baffle it replaces the lower half-space, with frame none it stands in "
                         "free air (its outside reflects), with a circle or square frame it "
                         "sits under the frame (docs/enclosures.md). Needs air.enabled to act",
                         kind=str, choices=ENCLOSURES),
        "enclosure_depth": Key("m", None, "depth L of the enclosure below the membrane plane "
                               "(bowl: the cap's depth at its centre)", minimum=0, maximum=10,
                               open_min=True, derived="geometry.outer_radius"),
        "enclosure_radius": Key("m", None, "radius of the cylinder (bowl: of the cap's rim) "
                                "sealed to the membrane plane; >= geometry.outer_radius, the "
                                "top between r_o and this radius is rigid wall (with frame "
                                "circle: equal to geometry.frame_radius); ignored for box (its side "
                                "is geometry.frame_side)", minimum=0, maximum=10,
                                open_min=True, derived="geometry.outer_radius"),
        "enclosure_vent_radius": Key("m", 0.0, "radius of a circular vent in the enclosure's "
                                     "bottom, centred on the axis, open to the outside air "
                                     "(region boundary 'vent'); 0 = sealed", minimum=0,
                                     maximum=10),
    },
    "membrane": {
        "thickness": Key("m", 100e-6, "film thickness h0 before pre-stretch (Table 1)",
                         minimum=0, maximum=0.01, open_min=True),
        "prestretch": Key(None, 1.2, "equibiaxial pre-stretch lambda_p (Table 1)",
                          minimum=1, maximum=10, open_min=True),
        "density": Key("kg/m^3", 1490.0, "density rho0 incl. electrodes (Table 1)",
                       minimum=0, maximum=1e5, open_min=True),
        "relative_permittivity": Key(None, 2.8, "relative permittivity eps_r (Table 1)",
                                     minimum=1, maximum=1e4),
        "c10": Key("Pa", 228.5e3, "Mooney-Rivlin c10 of eq. (20) (Sect. 5.1)",
                   minimum=0, maximum=1e9, open_min=True),
        "c20": Key("Pa", 8.4e3, "Mooney-Rivlin c20 of eq. (20)", minimum=-1e9, maximum=1e9),
        "c01": Key("Pa", -28.6e3, "Mooney-Rivlin c01 of eq. (20)", minimum=-1e9, maximum=1e9),
        "loss_factor": Key(None, 0.0, "hysteretic loss factor eta of the membrane's elastic "
                           "stiffness in `response` (K_el -> (1 - i eta) K_el for e^{-i omega t}; "
                           "the electrostatic part, the spring and the air stay lossless)",
                           minimum=0, maximum=1),
        "rayleigh_alpha": Key("1/s", 0.0, "mass-proportional Rayleigh damping alpha of the "
                              "membrane (and disc): C = alpha M + beta K, K the whole tangent "
                              "(material + initial stress + electrostatic); the eigen step then "
                              "solves (K - i omega C - omega^2 M) x = 0 (fields e^{-i omega t}, "
                              "decaying modes Im f < 0); modal damping ratio alpha/(2 omega) + "
                              "beta omega/2", minimum=0, maximum=1e6),
        "rayleigh_beta": Key("s", 0.0, "stiffness-proportional Rayleigh damping beta "
                             "(see membrane.rayleigh_alpha)", minimum=0, maximum=1.0),
        "prony": Key(None, [], "viscoelastic membrane: a generalised Maxwell (Prony) series on "
                     "the material part of the tangent, list of {modulus_ratio: g_j (to the "
                     "long-term modulus of eq. (20), which the prestress uses), "
                     "relaxation_time: tau_j [s]}; the material tangent becomes "
                     "K_mat (1 + sum g_j (-i omega tau_j)/(1 - i omega tau_j)); [] = elastic",
                     kind=list),
        "prestretch_anisotropy": Key(None, 0.0, "anisotropy e of the pre-stretch: the film is "
                                     "pre-stretched by membrane.prestretch * (1 + e) along "
                                     "membrane.prestretch_axis and * (1 - e) across it, then "
                                     "clamped in the round frame (thickness h0 / (lambda_p^2 "
                                     "(1 - e^2))); the film must stay in tension across the "
                                     "axis (the prestress refuses a slack one; G1 at 0 V: e < 0.34); "
                                     "0 = equibiaxial. 3-D engine, or the axisymmetric one's "
                                     "perturbation path within its range "
                                     "(docs/imperfections.md)",
                                     minimum=0, maximum=0.5),
        "prestretch_axis": Key("deg", 0.0, "direction of the larger pre-stretch, "
                               "counter-clockwise from the x axis", minimum=-360,
                               maximum=360),
        "thickness_variation": Key(None, [], "uneven film: a list of {order: k >= 1, "
                                   "amplitude: a (|a| < 1), angle: degrees (default 0)}, the "
                                   "thickness h0 (1 + sum a cos k (theta - angle)) on mass, "
                                   "stiffness and field alike; sum |a| < 1; [] = uniform. "
                                   "3-D engine, or the axisymmetric one's perturbation path "
                                   "within its range (docs/imperfections.md)", kind=list,
                                   reader=read_thickness_variation),
    },
    "disc": {
        "mass": Key("kg", 3.0e-3, f"rigid disc mass M_d ({G1}; G2: 1.9 g)",
                    minimum=0, maximum=100, open_min=True),
        "motion": Key(None, "held", "disc held fixed (structural modes, Sect. 2) or rigid on the "
                      "biasing spring (adds the pumping mode P1)", kind=str,
                      choices=("held", "spring")),
    },
    "spring": {
        "stiffness": Key("N/m", 52.0, "biasing spring stiffness k_d (Table 1)",
                         minimum=0, maximum=1e7),
        "mass": Key("kg", 1.8e-3, "biasing spring mass M_s (Table 1, Annex I)",
                    minimum=0, maximum=100),
        "length": Key("m", 0.030, "biasing spring length L_s (Table 1, Annex I)",
                      minimum=0, maximum=10, open_min=True),
    },
    "load": {
        "z": Key("m", 0.0, "axial disc displacement z from the flat plane (Sect. 2)",
                 minimum=0, maximum=1.0),
        "voltage": Key("V", 0.0, "bias voltage V_b across the film", minimum=0, maximum=1e5),
    },
    "air": {
        "enabled": Key(None, False, "couple the membrane to the air (Sect. 3.1.2); "
                       "false = dry, in-vacuo modes", kind=bool),
        "density": Key("kg/m^3", 1.204, "air density rho_a (20 C, 1 atm)",
                       minimum=0, maximum=100, open_min=True),
        "sound_speed": Key("m/s", 343.0, "speed of sound c_a (20 C)",
                           minimum=0, maximum=1e4, open_min=True),
        "domain_radius": Key("m", None, "radius of the air sphere inside the PML (Sect. 5.1)",
                             minimum=0, maximum=10, open_min=True,
                             derived="3.5 * geometry.outer_radius"),
        "pml_thickness": Key("m", None, "radial thickness of the PML shell (Sect. 5.1)",
                             minimum=0, maximum=10, open_min=True,
                             derived="0.5 * geometry.outer_radius"),
        "outside": Key(None, True, "mesh the outside air (the PML sphere); false = only the "
                       "air inside the enclosure (needs geometry.enclosure != none, "
                       "air.enabled and no vent): the membrane over a sealed cavity in vacuo",
                       kind=bool),
        "min_membrane_energy": Key(None, 0.1, "coupled modes whose membrane (+ disc) share of "
                                   "the kinetic energy is below this are air/PML modes "
                                   "(kind air); 0.1 keeps structural modes with added "
                                   "masses up to 9x their own", minimum=0, maximum=1),
    },
    "mesh": {
        "membrane_size": Key("m", 3e-3, "element size on the membrane", minimum=0,
                             maximum=1.0, open_min=True),
        "air_size": Key("m", None, "largest element size in the air", minimum=0, maximum=10,
                        open_min=True, derived="0.5 * geometry.outer_radius"),
        "grading": Key(None, 0.3, "Netgen grading: how fast elements grow away from the membrane",
                       minimum=0.05, maximum=1.0),
        "order": Key(None, 3, "polynomial order of the membrane displacement", kind=int,
                     minimum=1, maximum=8),
        "pressure_order": Key(None, 2, "polynomial order of the air pressure", kind=int,
                              minimum=1, maximum=6),
        "curve_order": Key(None, 3, "order of the curved geometry (circles)", kind=int,
                           minimum=1, maximum=8),
        "symmetry": Key(None, "quarter", "coupled solve: quarter = mesh one quadrant and "
                        "solve the four mirror-symmetry classes apart (the device is symmetric "
                        "about x = 0 and y = 0); none = mesh it whole. Dry studies mesh the "
                        "whole plane", kind=str, choices=("quarter", "none")),
        "engine": Key(None, "auto", "FE engine: axisymmetric = meridian (r, z) mesh, one 2-D "
                      "problem per circumferential order m (frame none, baffle or circle); "
                      "3d = the 3-D mesh (any frame; needed for the square frame); auto = "
                      "axisymmetric where the geometry allows (an imperfect "
                      "device: where its perturbation path takes it, modes dry or in air), "
                      "else "
                      "3d", kind=str,
                      choices=ENGINES),
    },
    "prestress": {
        "z_steps": Key(None, 4, "initial number of load steps in z", kind=int,
                       minimum=1, maximum=1000),
        "voltage_steps": Key(None, 2, "initial number of load steps in V_b", kind=int,
                             minimum=1, maximum=1000),
        "max_cuts": Key(None, 8, "how many times a load step may be halved", kind=int,
                        minimum=0, maximum=30),
        "newton_tol": Key(None, 1e-10, "Newton tolerance on the residual, relative to the "
                          "first residual of the step", minimum=0, maximum=1e-3, open_min=True),
        "max_newton_iter": Key(None, 25, "Newton iterations per load step", kind=int,
                               minimum=1, maximum=500),
    },
    "eigen": {
        "f_min": Key("Hz", 0.0, "lower end of the frequency band", minimum=0, maximum=1e6),
        "f_max": Key("Hz", 1000.0, "upper end of the frequency band", minimum=0,
                     maximum=1e6, open_min=True),
        "max_modes": Key(None, 200, "most modes returned in the band", kind=int,
                         minimum=1, maximum=5000),
        "backend": Key(None, "superlu", "sparse factorisation: superlu (SciPy, in METIS "
                       "nested-dissection order: solves 2.5-3x faster than umfpack here), "
                       "umfpack (ships with NGSolve) or pardiso (needs `pip install mkl`)",
                       kind=str,
                       choices=("umfpack", "pardiso", "superlu")),
        "max_damping_ratio": Key(None, 0.05, "coupled solve: the band also spans |Im f| <= "
                                 "this * f_max, so every mode with damping ratio up to it "
                                 "is found (radiation damping of G1's membrane modes at "
                                 "2 kV: (0,1) 2.0e-2 in a baffle, 3.0e-2 at z = 16 mm, "
                                 "3e-4..6e-4 under the square frame; (1,1), (0,2) "
                                 "1e-4..4e-4 in a baffle; more damped air/PML modes may be "
                                 "left out)",
                                 minimum=0, maximum=1, open_min=True),
        "residual_tol": Key(None, 1e-6, "largest accepted relative residual "
                            "|Ax - lambda Bx| / (|A| |x|)", minimum=0, maximum=1e-2,
                            open_min=True),
        "factor_memory_gb": Key(None, 1.0, "memory (GB) the sparse LU factors of the 3-D "
                                "coupled sectors may take at once: sectors run side by "
                                "side on the cores while their estimated factors fit, else "
                                "one after the other (0.65 m drum: ~0.57 GB a sector, so "
                                "one at a time and the whole solve under 1.6 GB; 1.2 runs "
                                "two at a time, 2x faster, 2.1 GB; G1: 0.08 GB)",
                                minimum=0, maximum=1e4, open_min=True),
    },
    "output": {
        "directory": Key(None, None, "where results go, relative to the working directory and "
                         "inside it (README: output folders; --out writes elsewhere)",
                         kind=str, derived="results/<study file name>"),
        "paraview": Key(None, True, "write ParaView .pvd/.vtu files", kind=bool),
        "plots": Key(None, True, "write PNG plots", kind=bool),
    },
}

# Reduced lumped-parameter model (Sect. 3.2, Annex I) and its chirp excitation (Sect. 4.2).
SCHEMA["reduced"] = {
    "rings": Key(None, 6, "number n of rings of the ring model (Sect. 3.2.1; Sect. 5.1 uses 6)",
                 kind=int, minimum=2, maximum=400),
    "modes": Key(None, "auto", "modes kept in the truncation (eq. 18): auto = P1, (0,1), (0,2) "
                 "with disc.motion = spring (Sect. 5.1), (0,1), (0,2) with the disc held; or a "
                 "comma-separated list of P1 and (0,n), e.g. 'P1, (0,1), (0,2), (0,3)'", kind=str),
    "modes_json": Key(None, None, "modes.json of a coupled FE solve: its (0,n) frequencies set the "
                      "added masses m_ad = k/w_FE^2 - m (eq. 19); path relative to the working "
                      "directory", kind=str, derived="none (no FE frequencies)"),
    "coupled_freq_p1": Key("Hz", None, "coupled frequency of P1; sets its added mass (eq. 19) "
                           "instead of reduced.pumping_added_mass", minimum=0, maximum=1e6,
                           open_min=True, derived="none"),
    "coupled_freq_01": Key("Hz", None, "coupled (in-air) frequency of (0,1); overrides "
                           "reduced.modes_json; none and no modes_json = dry (m_ad = 0)",
                           minimum=0, maximum=1e6, open_min=True, derived="none"),
    "coupled_freq_02": Key("Hz", None, "coupled (in-air) frequency of (0,2); as coupled_freq_01",
                           minimum=0, maximum=1e6, open_min=True, derived="none"),
    "pumping_added_mass": Key(None, "spring", "added mass of P1 without reduced.coupled_freq_p1: "
                              "spring = the biasing spring's distributed mass M_s (P1 then sits "
                              "where Annex I, eq. 22, puts it), none = m_ad,1 = 0 as in Sect. 5.1",
                              kind=str, choices=("spring", "none")),
    "damping_p1": Key("1/s", 45.0, "modal damping over structural modal mass b/m of P1 "
                      "(Sect. 5.3)", minimum=0, maximum=1e6),
    "damping_01": Key("1/s", 245.0, "b/m of (0,1) (Sect. 5.3)", minimum=0, maximum=1e6),
    "damping_02": Key("1/s", 57.0, "b/m of (0,2) (Sect. 5.3)", minimum=0, maximum=1e6),
    "damping_higher": Key("1/s", 57.0, "b/m of (0,3) and higher (not calibrated in the paper; "
                          "default: that of (0,2))", minimum=0, maximum=1e6),
    "scan_radii": Key(None, 5, "radial positions of the scan grid of the average spectra, centres "
                      "of equal bands of the projected width (Fig. 5d: 80 membrane points; the "
                      "axisymmetric model needs only their radii)", kind=int, minimum=1,
                      maximum=1000),
}
SCHEMA["excitation"] = {
    "amplitude": Key("V", 100.0, "chirp amplitude V~ on top of load.voltage (Sect. 4.2)",
                     minimum=0, maximum=1e5, open_min=True),
    "f_start": Key("Hz", 0.0, "chirp start frequency (Sect. 4.2)", minimum=0, maximum=1e6),
    "f_end": Key("Hz", 1000.0, "chirp end frequency = last spectral line (Sect. 4.2)",
                 minimum=0, maximum=1e6, open_min=True),
    "duration": Key("s", 0.8, "chirp period and FFT window; line spacing 1/duration "
                    "(Sect. 4.2: 800 ms, 1.25 Hz)", minimum=0, maximum=100, open_min=True),
    "sample_time": Key("s", 0.4e-3, "sampling interval of the chirp (Sect. 4.2)", minimum=0,
                       maximum=1.0, open_min=True),
}

# Forced harmonic response of the coupled FE and its sound (copdea_fem.forced_response).
SCHEMA["response"] = {
    "method": Key(None, "auto", "auto = on the 3-D engine reduced when the membrane states "
                  "its own loss (loss_factor, Rayleigh or Prony), else reduced_modal; modal on "
                  "the axisymmetric engine; modal = "
                  "superposition of the coupled m = 0 modes with the "
                  "paper's modal damping reduced.damping_* and a residual correction; direct = "
                  "one sparse solve per line with membrane.loss_factor (no modal b/m); reduced = "
                  "the direct path's model (loss factor, Rayleigh, Prony; no modal b/m) projected "
                  "on a rational Krylov basis from a few shifts in the band; reduced_modal = "
                  "that basis without a loss of its own, its modes damped with the paper's "
                  "reduced.damping_* as the modal path damps its modes (no loss factor, "
                  "Rayleigh or Prony) (docs/response.md)",
                  kind=str, choices=("auto", "modal", "direct", "reduced", "reduced_modal")),
    "reduced_tol": Key(None, 1e-7, "reduced path: largest relative residual "
                       "|T(omega) x_r - F| / |F| accepted on every line; shifts are added where "
                       "it is largest", minimum=1e-14, maximum=1e-2),
    "modal_band": Key(None, 2.0, "modal path: modes with Re f and |Im f| up to this times the "
                      "last line (G1: 2 keeps the modal path within 0.4 % of the direct one up "
                      "to 1 kHz)", minimum=1, maximum=20),
    "microphone_distance": Key("m", 1.0, "distance of the default microphone 'axis' on the +z "
                               "axis in front of the membrane", minimum=0, maximum=1e4,
                               open_min=True),
    "microphones": Key(None, "", "more microphones: 'name = x, y, z; ...' (lengths, e.g. "
                       "'side = 0.5 m, 0 m, 0.5 m'; distinct names, not at the origin, z != 0 "
                       "with a baffle); SPL in spl.csv as spl_<name>", kind=str),
    "peaks": Key(None, 3, "operating-deflection shapes written at this many spectrum peaks",
                 kind=int, minimum=0, maximum=50),
}

# Physical effects the reduced model can switch on or scale (copdea_fem.diagnosis):
# each default reproduces the model without the key.
SCHEMA["effects"] = {
    "stiffness_scale": Key(None, 1.0, "uniform factor on c10, c20, c01 of eq. (20) in the reduced "
                           "model and the FE: electrode stiffness or pre-stretch loss (diagnose effect "
                           "uniform_stiffness); 1 = the membrane keys as given", minimum=0,
                           maximum=10, open_min=True),
    "maxwell_scale": Key(None, 1.0, "factor on the electrostatic term V^2/2 C of eq. (10) in the "
                         "reduced model's static equilibrium and K_s (eq. 14): the Maxwell-stress "
                         "softening (diagnose effect electrostatic_softening); 1 = eq. (7) with "
                         "membrane.relative_permittivity, 0 = none; the forcing V_b V~ dC/dq "
                         "keeps the nominal permittivity (in the FE: a factor on the "
                         "permittivity, the forcing included)", minimum=0, maximum=10),
    "air_added_mass": Key(None, "none", "added mass of the (0,n) modes where no coupled FE "
                          "frequency is given (eq. 19): none = dry, incompressible = "
                          "incompressible air on both faces of a baffled membrane "
                          "(copdea_fem.reduced.airmass; diagnose effect air_loading)", kind=str,
                          choices=("none", "incompressible")),
    "air_mass_scale": Key(None, 1.0, "factor on the added mass of every (0,n) mode, whatever its "
                          "source (estimate, modes.json, reduced.coupled_freq_0n)", minimum=0,
                          maximum=10),
    "viscoelastic_strength": Key(None, 0.0, "strength Delta of a standard linear solid: the "
                                 "membrane's elastic stiffness in K_s is multiplied by the storage "
                                 "factor 1 + Delta (w tau)^2 / (1 + (w tau)^2) (quasi-linear "
                                 "visco-elasticity; diagnose effect viscoelastic_stiffening); "
                                 "0 = elastic", minimum=0, maximum=100),
    "viscoelastic_time": Key("s", 2e-4, "relaxation time tau of that standard linear solid",
                             minimum=0, maximum=10, open_min=True),
}

# The electrode split into segments driven apart (copdea_fem.fe.forced.electrode); written
# in a resolved study only when given (OPTIONAL_SECTIONS).
SCHEMA["electrodes"] = {
    "segments": Key(None, [], "the electrode split into segments, each driven by its own AC "
                    "voltage on the shared bias load.voltage: a list of {name, theta: [from, to] "
                    "degrees counter-clockwise from the x axis (from > to wraps through 0; "
                    "[0, 360] the whole circle), r: [from, to] metres on the flat pre-stretched "
                    "membrane (default the whole annulus), drive: {amplitude: AC volts per volt "
                    "of the input (default 1), phase: degrees (default 0)}}; segments may not "
                    "overlap; [] = one electrode over the whole membrane (docs/response.md)",
                    kind=list, reader=read_segments),
}

# Point masses on the membrane or the disc (copdea_fem.fe.linearise); written in a resolved
# study only when given (OPTIONAL_SECTIONS).
SCHEMA["imperfections"] = {
    "point_masses": Key(None, [], "lumped masses on the device: a list of {mass: kg > 0, r: "
                        "metres on the flat pre-stretched device, below "
                        "geometry.outer_radius (r <= geometry.inner_radius: on the rigid disc, "
                        "adding to its mass), theta: degrees counter-clockwise from the x "
                        "axis (default 0)}; [] = none. 3-D engine (docs/imperfections.md)",
                        kind=list, reader=read_point_masses),
}

#: Sections written in a resolved study (and hashed) only when a key differs from its
#: default, so that a study without them resolves as it did before they existed.
QUARTER_POINTS = (0.25, 0.5, 0.75)
"""Q1, Q2, Q3: fractions of the width r_o - r_i from the inner edge (Sect. 5.3, Fig. 5d); the
points of the reduced model's spectra and of the forced response's point outputs."""

#: The mode labels with their own ``reduced.damping_*`` key (:func:`damping_key`).
DAMPING_KEYS = {"P1": "damping_p1", "(0,1)": "damping_01", "(0,2)": "damping_02"}


def damping_key(label: str) -> str:
    """The study key holding b/m [1/s] of a mode label (Sect. 5.3: P1, (0,1), (0,2);
    ``reduced.damping_higher`` past (0,2))."""
    return "reduced." + DAMPING_KEYS.get(label, "damping_higher")


OPTIONAL_SECTIONS = ("electrodes", "imperfections")
#: Keys of the other sections written (and hashed) only when they differ from their
#: default, for the same reason.
OPTIONAL_KEYS = {"membrane": ("prestretch_anisotropy", "prestretch_axis",
                              "thickness_variation")}

#: Most elements across the membrane width r_o - r_i that both engines mesh: the smallest
#: mesh.membrane_size, and the narrowest ring of a circular frame, is (r_o - r_i) / this.
#: Netgen's 2-D mesher failed on G1's meridian (width 18.5 mm) at 460 and 925 elements
#: across (0.04, 0.02 mm; 0.03 and 0.06 mm passed) and on a ring 1e-10 m wide (a ring
#: within round-off of r_o crashed it); 200 keeps a margin of 2.  The 3-D engine's resource
#: guard refuses such sizes anyway (G1 at 0.09 mm: ~1e7 unknowns).
MAX_ELEMENTS_ACROSS = 200


# Top-level keys that are not sections: free text, and the provenance block a
# resolved study carries (so a resolved study can be run again as it is).
META_KEYS = ("name", "description", "provenance")


def reference_table() -> str:
    """Markdown table of every key, generated from :data:`SCHEMA` (for the README)."""
    rows = ["| key | unit | default | allowed | description |", "|---|---|---|---|---|"]
    for section, keys in SCHEMA.items():
        for key, spec in keys.items():
            default = spec.derived if spec.default is None else spec.default
            if isinstance(default, bool):
                default = str(default).lower()
            elif isinstance(default, float):
                default = f"{default:g}"
            rows.append(f"| `{section}.{key}` | {spec.unit or '-'} | {default} | "
                        f"{spec.allowed()} | {spec.description} |")
    return "\n".join(rows)
