"""Typed schema of ``study.yaml``: units, bounds, defaults and descriptions.

A study is read from YAML, overridden by ``--set SECTION.KEY=VALUE`` strings,
validated key by key and then across keys, and resolved to SI numbers with
every default filled in -- all before any meshing.  Physical values accept a
unit string (``"35.5 mm"``, ``"2 kV"``, ``"228.5 kPa"``) or a plain SI number.

Run ``python -m copdea_fem.study`` to print the reference table of the README.
"""

from __future__ import annotations

import copy
import functools
import math
import numbers
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from copdea_fem.folders import package_versions
from copdea_fem.inputs import parse_yaml, preview, read_yaml
from copdea_fem.units import fast_to_si


class StudyError(ValueError):
    """A study key has a value outside what is allowed; the message says which.

    Raised for every bad input, before any work where it can be found then: a study file
    or key, a command's argument, an input file (the CLI's exit 2).  Subclasses:
    :class:`copdea_fem.sweeps.axes.SweepError` (a sweep file) and
    :class:`copdea_fem.diagnosis.measured.MeasuredDataError` (a measured data set).

    Parameters
    ----------
    message : str
        The key (or argument or file), its value and what is allowed.
    """


@dataclass(frozen=True)
class Key:
    """One study key: SI unit, default, bounds and meaning.

    ``unit`` is the SI unit the value is converted to (``None`` for a pure
    number, a switch or a choice).  ``default=None`` with ``derived`` set means
    the default is computed from other keys (see :func:`_derived_defaults`).
    """

    unit: str | None
    default: Any
    description: str
    kind: type = float
    minimum: float | None = None
    maximum: float | None = None
    open_min: bool = False          # minimum excluded
    choices: tuple | None = None
    derived: str | None = None      # text of the derived default, for the docs

    def allowed(self) -> str:
        if self.choices:
            return "one of " + ", ".join(map(str, self.choices))
        if self.kind is list:
            return "a list (see the description)"
        if self.kind is bool:
            return "true or false"
        if self.kind is str:
            return "any text"
        lo = "" if self.minimum is None else f"{self.minimum:g}"
        hi = "" if self.maximum is None else f"{self.maximum:g}"
        unit = f" {self.unit}" if self.unit else ""
        if self.minimum is not None and self.maximum is not None:
            bracket = "(" if self.open_min else "["
            return f"{bracket}{lo}, {hi}]{unit}"
        if self.minimum is not None:
            return f"{'>' if self.open_min else '>='} {lo}{unit}"
        if self.maximum is not None:
            return f"<= {hi}{unit}"
        return "any number" + unit


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
                      "axisymmetric where the geometry allows, else 3d", kind=str,
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

#: Most elements across the membrane width r_o - r_i that both engines mesh: the smallest
#: mesh.membrane_size, and the narrowest ring of a circular frame, is (r_o - r_i) / this.
#: Netgen's 2-D mesher failed on G1's meridian (width 18.5 mm) at 460 and 925 elements
#: across (0.04, 0.02 mm; 0.03 and 0.06 mm passed) and on a ring 1e-10 m wide (a ring
#: within round-off of r_o crashed it); 200 keeps a margin of 2.  The 3-D engine's resource
#: guard refuses such sizes anyway (G1 at 0.09 mm: ~1e7 unknowns).
MAX_ELEMENTS_ACROSS = 200

#: Longest text read as a quantity ("35.5 mm", "1.5e-3 kg/m^3").
MAX_QUANTITY_CHARACTERS = 100

# Top-level keys that are not sections: free text, and the provenance block a
# resolved study carries (so a resolved study can be run again as it is).
META_KEYS = ("name", "description", "provenance")


@functools.lru_cache(maxsize=1)
def unit_registry():
    """pint's unit registry, made once (slow to build): the fallback of :func:`convert_value`
    for units :mod:`copdea_fem.units` does not know."""
    import pint
    return pint.UnitRegistry()


#: Values this many units in the last place apart count as equal where a bound is open
#: (``>``) or two keys must differ: a unit conversion rounds ("35.5 mm" is
#: 35.5 * 1e-3 = 0.035500000000000004 m, one ulp above 0.0355).
ROUND_OFF_ULPS = 4


def above(value: float, bound: float) -> bool:
    """``value > bound`` beyond round-off (:data:`ROUND_OFF_ULPS`): a value within a few
    ulps of an open bound is on it, as the number written without a unit would be."""
    return value - bound > ROUND_OFF_ULPS * math.ulp(max(abs(value), abs(bound)))


def apart(first: float, second: float) -> bool:
    """Whether two values differ beyond round-off (:func:`above` either way)."""
    return above(first, second) or above(second, first)


def _fail(key: str, value: Any, allowed: str, why: str = "") -> StudyError:
    why = f" ({why})" if why else ""
    return StudyError(f"{key} = {preview(value)} is not allowed{why}; allowed: {allowed}")


def convert_value(key: str, spec: Key, value: Any) -> Any:
    """Turn one raw value into its SI value, checking type, unit and bounds."""
    if value is None and spec.default is None:
        return None
    if spec.kind is list:
        return _LIST_KEYS[key](key, value)
    if spec.kind is bool:
        if not isinstance(value, bool):
            raise _fail(key, value, spec.allowed())
        return value
    if spec.kind is str:
        if not isinstance(value, str) or (spec.choices and value not in spec.choices):
            raise _fail(key, value, spec.allowed())
        return value
    number = _to_si(key, spec, value)
    if not math.isfinite(number):
        raise _fail(key, value, spec.allowed(), "not a finite number")
    if spec.kind is int:
        if not float(number).is_integer():
            raise _fail(key, value, "an integer " + spec.allowed())
        number = int(number)
    number = number + 0        # -0.0 is 0
    lo, hi = spec.minimum, spec.maximum
    if (lo is not None and (number < lo or (spec.open_min and not above(number, lo)))) or (
            hi is not None and number > hi):
        shown = value if not isinstance(value, str) else f"{value} = {number:g} {spec.unit or ''}"
        raise _fail(key, shown, spec.allowed())
    return number


#: Prony series: at most this many terms (each adds a block of internal variables).
MAX_PRONY_TERMS = 8
PRONY_ALLOWED = ("a list of at most 8 mappings {modulus_ratio: number in (0, 1000], "
                 "relaxation_time: time in (0, 1000] s, e.g. '1 ms'}")


def _prony_terms(key: str, value: Any) -> list:
    """``membrane.prony`` -> ``[{"modulus_ratio": g_j, "relaxation_time": tau_j [s]}, ...]``."""
    if value is None:
        value = []
    if not isinstance(value, (list, tuple)) or len(value) > MAX_PRONY_TERMS:
        raise _fail(key, value, PRONY_ALLOWED)
    terms = []
    for index, item in enumerate(value):
        where = f"{key}[{index}]"
        if not isinstance(item, dict) or set(item) != {"modulus_ratio", "relaxation_time"}:
            raise _fail(where, item, PRONY_ALLOWED, "each term needs exactly the keys "
                        "modulus_ratio and relaxation_time")
        ratio = convert_value(f"{where}.modulus_ratio", Key(None, 0.0, "", minimum=0, maximum=1e3,
                                                       open_min=True), item["modulus_ratio"])
        tau = convert_value(f"{where}.relaxation_time", Key("s", 0.0, "", minimum=0, maximum=1e3,
                                                       open_min=True), item["relaxation_time"])
        terms.append({"modulus_ratio": ratio, "relaxation_time": tau})
    return terms


_LIST_KEYS = {"membrane.prony": _prony_terms}


def convert_quantity(key: str, value: Any, unit: str, minimum: float | None = None,
                     maximum: float | None = None) -> float:
    """One value of a compound key (e.g. a coordinate in a list) to SI ``unit``, bounds
    checked; a bare number is already SI.  Raises StudyError naming ``key``."""
    return convert_value(key, Key(unit, 0.0, key, minimum=minimum, maximum=maximum), value)


#: A bare number as people write it, read as a number in SI (YAML 1.1 reads ``3e-6`` and
#: ``5E5``, without a dot, as text; pint would read the ``e`` as the elementary charge).
_PLAIN_NUMBER = re.compile(r"[+-]?(?:\d(?:_?\d)*(?:\.(?:\d(?:_?\d)*)?)?|\.\d(?:_?\d)*)"
                           r"(?:[eE][+-]?\d+)?")
#: The texts of a number that is not finite (Python's and YAML's spellings).
_NOT_FINITE = re.compile(r"[+-]?\.?(?:nan|inf|infinity)", re.IGNORECASE)


def _to_si(key: str, spec: Key, value: Any) -> float:
    if isinstance(value, numbers.Real) and not isinstance(value, bool):   # numpy's too
        try:
            return float(value)
        except OverflowError:                   # an integer of more than 308 digits
            return math.inf
    if not isinstance(value, str):
        raise _fail(key, value, spec.allowed(), "expected a number"
                    + (f" or a quantity like '1.5 {_example_unit(spec.unit)}'" if spec.unit else ""))
    if len(value) > MAX_QUANTITY_CHARACTERS:    # pint takes minutes on 100 000 digits
        raise _fail(key, value, spec.allowed(), f"longer than {MAX_QUANTITY_CHARACTERS} "
                    "characters, not a quantity")
    text = value.strip()
    if _NOT_FINITE.fullmatch(text):
        raise _fail(key, value, spec.allowed(), "not a finite number")
    if _PLAIN_NUMBER.fullmatch(text):
        return float(text)
    fast = fast_to_si(value.strip(), spec.unit)     # "16 mm" without pint's slow start
    if fast is not None:
        return fast
    import pint
    try:
        quantity = unit_registry().Quantity(value.strip())
    except Exception as exc:  # pint raises several types for unparsable text
        raise _fail(key, value, spec.allowed(), f"cannot read it as a quantity: {exc}") from None
    try:
        return float(quantity.to(spec.unit or "dimensionless").magnitude)
    except pint.DimensionalityError:
        expected = f"a quantity in {spec.unit}" if spec.unit else "a pure number"
        raise _fail(key, value, spec.allowed(), f"wrong unit, expected {expected}") from None


def _example_unit(unit: str | None) -> str:
    return {"m": "mm", "V": "kV", "Pa": "kPa", "kg": "g", "Hz": "Hz"}.get(unit, unit or "")


class Study:
    """A validated study: nested ``{section: {key: SI value}}`` plus its name.

    Index like a dict: ``study["load"]["voltage"]`` [V].
    """

    def __init__(self, values: dict[str, dict[str, Any]], name: str, description: str = ""):
        self.values = values
        self.name = name
        self.description = description

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self.values[section]

    def get(self, dotted: str) -> Any:
        section, key = dotted.split(".", 1)
        return self.values[section][key]

    def replace(self, overrides: dict[str, Any]) -> "Study":
        """A new, re-validated study with ``{"section.key": value}`` overrides."""
        raw = copy.deepcopy(self.values)
        return parse_study(raw, overrides=overrides, name=self.name,
                           description=self.description)

    def checked(self) -> Study:
        """This study validated again, as a file would be: a study changed by hand after
        :func:`load_study` (``study["load"]["voltage"] = "2 kV"``, a key added, deleted or
        misspelled, a section replaced) comes back resolved to SI, or a :class:`StudyError`
        names the key.  Values already in SI are kept as they are."""
        if not isinstance(self.values, dict):
            raise _fail("study", self.values, "a mapping of sections")
        raw = {section: dict(keys) if isinstance(keys, dict) else keys
               for section, keys in self.values.items()}
        return parse_study(raw, name=self.name, description=self.description)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "description": self.description,
                **copy.deepcopy(self.values)}


#: What study overrides may be, for the messages.
OVERRIDES_ALLOWED = ('a mapping {"SECTION.KEY": value} (e.g. {"load.voltage": "1 kV"}) or a '
                     'list of "SECTION.KEY=VALUE" texts')


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """``["load.voltage=3 kV", ...]`` -> ``{"load.voltage": "3 kV"}`` (YAML-typed values)."""
    overrides: dict[str, Any] = {}
    if items is not None and not isinstance(items, (list, tuple)):
        raise _fail("overrides", items, OVERRIDES_ALLOWED)
    for item in items or []:
        if not isinstance(item, str):
            raise _fail("overrides", item, OVERRIDES_ALLOWED)
        if "=" not in item:
            raise StudyError(f"--set {preview(item)} is not allowed; allowed: SECTION.KEY=VALUE, "
                             "e.g. --set load.voltage='3 kV'")
        key, text = item.split("=", 1)
        try:
            value = parse_yaml(text, f"--set {key.strip()}", StudyError)
        except StudyError:
            value = text
        overrides[key.strip()] = text if value is None and text.strip() else value
    return overrides


def load_study(path: str | Path, overrides: dict[str, Any] | None = None) -> Study:
    """Read, override, validate and resolve a study file."""
    path = Path(path)
    raw = read_yaml(path, "study file", StudyError)
    name = raw.get("name") or path.stem
    return parse_study(raw, overrides=overrides, name=str(name),
                       description=str(raw.get("description", "")))


def parse_study(raw: dict[str, Any], overrides: dict[str, Any] | None = None,
                name: str = "study", description: str = "") -> Study:
    """Validate a raw nested mapping (plus dotted overrides) into a :class:`Study`."""
    raw = copy.deepcopy(raw)
    for key in raw:
        if key not in SCHEMA and key not in META_KEYS:
            raise _fail(key, "...", "sections " + ", ".join(SCHEMA) + " (and name, description)",
                        "unknown section")
    if overrides is not None and not isinstance(overrides, dict):
        raise _fail("overrides", overrides, OVERRIDES_ALLOWED)
    for dotted, value in (overrides or {}).items():
        if not isinstance(dotted, str):
            raise _fail(f"overrides key {dotted!r}", value, OVERRIDES_ALLOWED)
        section, _, key = dotted.partition(".")
        if section not in SCHEMA or key not in SCHEMA[section]:
            raise _unknown_key(dotted, value)
        if not isinstance(raw.get(section) or {}, dict):
            raise _fail(section, raw[section], "a mapping of keys")
        raw.setdefault(section, {})
        raw[section] = raw[section] or {}
        raw[section][key] = value

    values: dict[str, dict[str, Any]] = {}
    for section, keys in SCHEMA.items():
        given = raw.get(section) or {}
        if not isinstance(given, dict):
            raise _fail(section, given, "a mapping of keys: " + ", ".join(keys))
        for key, value in given.items():
            if key not in keys:
                raise _unknown_key(f"{section}.{key}", value)
        values[section] = {key: convert_value(f"{section}.{key}", spec,
                                         given[key] if key in given else spec.default)
                           for key, spec in keys.items()}
    _derived_defaults(values, name)
    _check_across_keys(values)
    return Study(values, name=name, description=description)


def _unknown_key(dotted: str, value: Any) -> StudyError:
    section = dotted.partition(".")[0]
    known = SCHEMA.get(section)
    allowed = ("keys " + ", ".join(f"{section}.{k}" for k in known)) if known else (
        "sections " + ", ".join(SCHEMA))
    return _fail(dotted, value, allowed, "unknown key")


def _derived_defaults(v: dict[str, dict[str, Any]], name: str) -> None:
    r_o = v["geometry"]["outer_radius"]
    for section, key, factor in (("air", "domain_radius", 3.5), ("air", "pml_thickness", 0.5),
                                 ("mesh", "air_size", 0.5)):
        if v[section][key] is None:
            v[section][key] = factor * r_o
    if v["geometry"]["frame_radius"] is None:
        v["geometry"]["frame_radius"] = 0.5 * v["geometry"]["frame_side"]
    g = v["geometry"]
    if g["enclosure_depth"] is None:
        g["enclosure_depth"] = r_o
    if g["enclosure_radius"] is None:   # under a circular frame: the whole ring is its lid
        g["enclosure_radius"] = g["frame_radius"] if g["frame"] == "circle" else r_o
    if v["output"]["directory"] is None:
        v["output"]["directory"] = f"results/{name}"


def _check_across_keys(v: dict[str, dict[str, Any]]) -> None:
    g, load = v["geometry"], v["load"]
    r_o, r_i = g["outer_radius"], g["inner_radius"]
    if not above(r_o, r_i):
        raise _fail("geometry.inner_radius", r_i, f"[0, {r_o:g}) m = below geometry.outer_radius")
    if 0 < r_i < 0.02 * r_o:
        raise _fail("geometry.inner_radius", r_i, f"0 or >= {0.02 * r_o:g} m (2 % of r_o)",
                    "a disc this small cannot be meshed sensibly")
    if g["frame"] == "square" and not above(g["frame_side"], 2 * r_o):
        raise _fail("geometry.frame_side", g["frame_side"],
                    f"> {2 * r_o:g} m = the membrane diameter 2 * geometry.outer_radius")
    R = v["air"]["domain_radius"]
    if g["frame"] == "square" and not above(R, g["frame_side"] / math.sqrt(2)):
        raise _fail("air.domain_radius", R, f"> {g['frame_side'] / math.sqrt(2):g} m",
                    "the square frame's corners must lie inside the air sphere")
    if not above(R, 1.2 * r_o):
        raise _fail("air.domain_radius", R, f"> {1.2 * r_o:g} m = 1.2 * geometry.outer_radius")
    width = r_o - r_i
    smallest = width / MAX_ELEMENTS_ACROSS
    if g["frame"] == "circle" and not (above(g["frame_radius"], r_o)
                                       and above(R, g["frame_radius"])):
        raise _fail("geometry.frame_radius", g["frame_radius"],
                    f"({r_o:g}, {R:g}) m = between geometry.outer_radius and air.domain_radius")
    if g["frame"] == "circle" and g["frame_radius"] - r_o < smallest:
        raise _fail("geometry.frame_radius", g["frame_radius"],
                    f">= {r_o + smallest:g} m = geometry.outer_radius + (r_o - r_i) / "
                    f"{MAX_ELEMENTS_ACROSS}", "a frame ring this narrow cannot be meshed")
    engine = v["mesh"]["engine"]
    if engine == "axisymmetric" and g["frame"] not in AXISYMMETRIC_FRAMES:
        raise _fail("mesh.engine", engine, f"3d or auto with geometry.frame = {g['frame']}",
                    "the axisymmetric engine needs frame none, baffle or circle")
    if engine == "3d" and g["frame"] == "circle":
        raise _fail("mesh.engine", engine, "axisymmetric or auto with geometry.frame = circle",
                    "the 3-D mesh has no circular frame")
    _check_enclosure(v)
    if r_i == 0:
        if load["z"] != 0:
            raise _fail("load.z", load["z"], "0 m when geometry.inner_radius = 0",
                        "a full membrane has no disc to displace")
        if v["disc"]["motion"] != "held":
            raise _fail("disc.motion", v["disc"]["motion"], "held when geometry.inner_radius = 0",
                        "a full membrane has no disc")
    if load["z"] > 2 * (r_o - r_i):
        raise _fail("load.z", load["z"], f"[0, {2 * (r_o - r_i):g}] m = 2 * (r_o - r_i)",
                    "meridian stretch beyond what the film survives")
    e = v["eigen"]
    if not above(e["f_max"], e["f_min"]):
        raise _fail("eigen.f_max", e["f_max"], f"> eigen.f_min = {e['f_min']:g} Hz")
    prony = v["membrane"]["prony"]
    if prony:
        # the rational eigen problem's relaxation spectrum lies on Re f = 0 from
        # |Im f| = 1/(2 pi tau_max (1 + sum g)) (copdea_fem.fe.eigen.damped): keep it out of
        # the band
        lowest = 1.0 / (2 * math.pi * max(t["relaxation_time"] for t in prony)
                        * (1 + sum(t["modulus_ratio"] for t in prony)))
        height = e["max_damping_ratio"] * e["f_max"]
        if e["f_min"] < 0.5 * lowest and lowest <= 2 * height:
            raise _fail("eigen.f_min", e["f_min"], f">= {0.5 * lowest:.4g} Hz with this "
                        "membrane.prony", f"the Prony relaxation spectrum (Re f = 0, |Im f| >= "
                        f"{lowest:.4g} Hz) would reach the band |Im f| <= eigen.max_damping_ratio"
                        f" * eigen.f_max = {height:.4g} Hz")
    if v["mesh"]["membrane_size"] > width / 2:
        raise _fail("mesh.membrane_size", v["mesh"]["membrane_size"],
                    f"<= {width / 2:g} m = half the membrane width",
                    "fewer than two elements across the membrane")
    if v["mesh"]["membrane_size"] < smallest:
        raise _fail("mesh.membrane_size", v["mesh"]["membrane_size"],
                    f">= {smallest:g} m = (r_o - r_i) / {MAX_ELEMENTS_ACROSS}",
                    f"more than {MAX_ELEMENTS_ACROSS} elements across the membrane: Netgen "
                    "cannot mesh it")
    _check_reduced_keys(v)
    listed_microphones(v["response"]["microphones"], g["frame"], g["enclosure"])
    m = v["membrane"]
    if v["response"]["method"] == "reduced_modal" and (
            m["loss_factor"] > 0 or m["rayleigh_alpha"] > 0 or m["rayleigh_beta"] > 0
            or m["prony"]):
        raise _fail("response.method", "reduced_modal", "auto, modal, direct or reduced with a "
                    "loss of the membrane's own (membrane.loss_factor, rayleigh_alpha, "
                    "rayleigh_beta or prony)", "the reduced basis's modes would not "
                    "diagonalise that loss")


def _check_enclosure(v: dict[str, dict[str, Any]]) -> None:
    """Cross-key checks of geometry.enclosure* and air.outside (docs/enclosures.md)."""
    g, air = v["geometry"], v["air"]
    enclosure, frame = g["enclosure"], g["frame"]
    if enclosure == "none":
        if not air["outside"]:
            raise _fail("air.outside", False, "true with geometry.enclosure = none",
                        "without an enclosure there is no air but the outside air")
        return
    r_o, depth, vent = g["outer_radius"], g["enclosure_depth"], g["enclosure_vent_radius"]
    if above(ENCLOSURE_MIN_DEPTH * r_o, depth):
        raise _fail("geometry.enclosure_depth", depth,
                    f">= {ENCLOSURE_MIN_DEPTH * r_o:g} m = {ENCLOSURE_MIN_DEPTH:g} * "
                    "geometry.outer_radius", "a thinner gap cannot be meshed sensibly")
    if enclosure == "box":
        if frame != "square":
            raise _fail("geometry.enclosure", enclosure, "cylinder or bowl with geometry.frame "
                        f"= {frame}", "a box sits under the square frame (frame: square)")
        half_width = 0.5 * g["frame_side"]
        farthest = math.hypot(half_width * math.sqrt(2), depth)
    else:
        radius = g["enclosure_radius"]
        if above(r_o, radius):
            raise _fail("geometry.enclosure_radius", radius,
                        f">= {r_o:g} m = geometry.outer_radius",
                        "the enclosure's rim is sealed to the membrane's rim")
        if frame == "circle" and apart(radius, g["frame_radius"]):
            raise _fail("geometry.enclosure_radius", radius,
                        f"{g['frame_radius']:g} m = geometry.frame_radius (its default with "
                        "frame circle)", "the enclosure sits under the circular frame, which "
                        "is its lid: a ring reaching past the enclosure's rim would need a "
                        "pressure jump outside the cavity, which the axisymmetric engine "
                        "does not carry")
        if frame == "square" and not above(0.5 * g["frame_side"], radius):
            raise _fail("geometry.enclosure_radius", radius,
                        f"< {0.5 * g['frame_side']:g} m = half geometry.frame_side",
                        "the enclosure sits under the square frame")
        if enclosure == "bowl" and above(depth, radius):
            raise _fail("geometry.enclosure_depth", depth,
                        f"(0, {radius:g}] m = at most geometry.enclosure_radius",
                        "a bowl is a spherical cap, at most a hemisphere")
        half_width = radius
        farthest = math.hypot(radius, depth)
    if not above(half_width, vent):
        raise _fail("geometry.enclosure_vent_radius", vent,
                    f"[0, {half_width:g}) m = narrower than the enclosure's bottom")
    if enclosure != "box":
        _check_enclosure_radii(g, vent, r_o)
    if vent > 0 and frame == "baffle":
        raise _fail("geometry.enclosure_vent_radius", vent, "0 with geometry.frame = baffle",
                    "with a baffle the enclosure replaces the lower half-space: no outside "
                    "air for the vent to open to")
    if vent > 0 and not air["outside"]:
        raise _fail("geometry.enclosure_vent_radius", vent, "0 with air.outside = false",
                    "a vent opens to the outside air")
    if not air["outside"] and not air["enabled"]:
        raise _fail("air.outside", False, "true when air.enabled = false",
                    "there is no air to keep")
    R = air["domain_radius"]
    if frame == "baffle" and above(half_width, ENCLOSURE_AIR_SHARE * R):
        raise _fail("air.domain_radius", R, f">= {half_width / ENCLOSURE_AIR_SHARE:g} m",
                    f"the enclosure's top (radius {half_width:g} m) must lie within "
                    f"{ENCLOSURE_AIR_SHARE:g} of the air sphere's radius")
    if frame != "baffle" and air["outside"] and above(farthest, ENCLOSURE_AIR_SHARE * R):
        raise _fail("air.domain_radius", R, f">= {farthest / ENCLOSURE_AIR_SHARE:g} m",
                    f"the enclosure's farthest point ({farthest:g} m from the centre) must lie "
                    f"within {ENCLOSURE_AIR_SHARE:g} of the air sphere's radius, with outside "
                    "air around it")


def _check_enclosure_radii(g: dict[str, Any], vent: float, r_o: float) -> None:
    """The radii where the meridian's lines meet: equal or :data:`ENCLOSURE_MIN_GAP` r_o
    apart (a vent of 0 is none; the frame's only with frame circle)."""
    gap = ENCLOSURE_MIN_GAP * r_o
    radii = {"geometry.inner_radius": g["inner_radius"], "geometry.outer_radius": r_o,
             "geometry.enclosure_radius": g["enclosure_radius"]}
    if g["frame"] == "circle":
        radii["geometry.frame_radius"] = g["frame_radius"]
    if 0 < vent < gap:
        raise _fail("geometry.enclosure_vent_radius", vent,
                    f"0 or >= {gap:g} m = {ENCLOSURE_MIN_GAP:g} * geometry.outer_radius",
                    "a smaller vent cannot be meshed")
    for name, radius in radii.items():
        if radius > 0 and vent > 0 and apart(vent, radius) and abs(vent - radius) < gap:
            raise _fail("geometry.enclosure_vent_radius", vent, f"equal to {name} = "
                        f"{radius:g} m or at least {gap:g} m from it",
                        "the lines meeting there cannot be meshed")
    for name in ("geometry.enclosure_radius", "geometry.frame_radius"):
        if name not in radii:
            continue
        for other, radius in radii.items():
            if other != name and apart(radii[name], radius) and abs(radii[name] - radius) < gap:
                raise _fail(name, radii[name], f"equal to {other} = {radius:g} m or at least "
                            f"{gap:g} m from it", "the lines meeting there cannot be meshed")


def engine_of(study) -> str:
    """The FE engine a study runs on: ``"axisymmetric"`` or ``"3d"`` (key mesh.engine).

    ``auto`` picks the axisymmetric engine for a frame none, baffle or circle with no
    enclosure, a cylinder or a bowl; else the 3-D engine.
    """
    engine = study["mesh"]["engine"]
    if engine == "auto":
        g = study["geometry"]
        axisymmetric = (g["frame"] in AXISYMMETRIC_FRAMES
                        and g.get("enclosure", "none") in AXISYMMETRIC_ENCLOSURES)
        return "axisymmetric" if axisymmetric else "3d"
    return engine


def dump_resolved(study: Study, path: str | Path) -> None:
    """Write the resolved study (SI, defaults filled in) plus package versions."""
    data = study.as_dict()
    data["provenance"] = package_versions()
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False))


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


def reduced_mode_labels(text: str, disc_motion: str) -> tuple[str, ...]:
    """Labels of ``reduced.modes``: ``"auto"`` or a comma-separated list of P1 and (0,n)."""
    import re
    if text.strip() == "auto":
        return (("P1",) if disc_motion == "spring" else ()) + ("(0,1)", "(0,2)")
    allowed = "auto, or a comma-separated list of P1 and (0,n) with n >= 1, e.g. 'P1, (0,1), (0,2)'"
    labels = []
    for item in re.findall(r"\([^)]*\)|[^,\s()]+", text):
        match = re.fullmatch(r"\(\s*0\s*,\s*([1-9]\d*)\s*\)", item)
        if match:
            labels.append(f"(0,{match.group(1)})")
        elif item.upper() == "P1":
            labels.append("P1")
        elif item:
            raise _fail("reduced.modes", text, allowed, f"cannot read {item!r}")
    if not labels or len(set(labels)) != len(labels):
        raise _fail("reduced.modes", text, allowed, "empty or repeated labels")
    if "P1" in labels and disc_motion != "spring":
        raise _fail("reduced.modes", text, "labels without P1 when disc.motion = held",
                    "the pumping mode needs the disc on the spring")
    return tuple(labels)


MICROPHONES_ALLOWED = "'name = x, y, z; ...' with lengths, e.g. 'side = 0.5 m, 0 m, 0.5 m'"
#: The name of the default microphone (on the +z axis at ``response.microphone_distance``);
#: a microphone of ``response.microphones`` may not take it.
DEFAULT_MICROPHONE = "axis"


def listed_microphones(text: str, frame: str = "square",
                       enclosure: str = "none") -> list[tuple[str, tuple[float, float, float]]]:
    """The microphones of ``response.microphones`` (``"name = x, y, z; ..."``, units
    allowed, a bare number in m): named positions (x, y, z) [m], checked.

    Refused (key ``response.microphones``): an item that is not ``name = x, y, z`` (a name of
    letters, digits and ``_``; three coordinates), a name given twice (the default
    microphone's, :data:`DEFAULT_MICROPHONE`, included), a coordinate that is not a length
    in [-1e4, 1e4] m, a point at the origin (the membrane's centre), and with
    ``frame = "baffle"`` a point on the rigid plane z = 0 (the Rayleigh integral is taken on
    the microphone's side of the baffle), and with a baffle over an enclosure a point
    below it (z < 0: the enclosure replaces the lower half-space).  Called when a study is read, so a bad list never
    reaches a solve; the forced response adds the default microphone
    (:func:`copdea_fem.forced_response.run.parse_microphones`).
    """
    key = "response.microphones"
    microphones = []
    names = {DEFAULT_MICROPHONE}
    text = text or ""
    for item in filter(None, (part.strip() for part in text.split(";"))):
        name, _, coordinates = item.partition("=")
        name = name.strip()
        values = [part.strip() for part in coordinates.split(",")]
        if not name or not name.replace("_", "").isalnum() or len(values) != 3:
            raise _fail(key, text, MICROPHONES_ALLOWED, f"cannot read {item!r}")
        if name in names:
            raise _fail(key, text, f"{MICROPHONES_ALLOWED} with distinct names",
                        f"microphone {name!r} repeated")
        position = tuple(convert_quantity(key, _number_or_text(value), "m", -1e4, 1e4)
                         for value in values)
        if not any(position):
            raise _fail(key, text, "a point away from the membrane centre",
                        f"microphone {name!r} at the origin")
        if frame == "baffle" and enclosure != "none" and position[2] < 0:
            raise _fail(key, text, "z > 0 with geometry.frame = baffle over an enclosure",
                        f"microphone {name!r} at z < 0 lies inside the enclosure's "
                        f"half-space (position {list(position)} m)")
        if frame == "baffle" and position[2] == 0:
            raise _fail(key, text, "z != 0 with geometry.frame = baffle", f"microphone {name!r} "
                        f"at z = 0 lies on the rigid plane (position {list(position)} m)")
        microphones.append((name, position))
        names.add(name)
    return microphones


def _number_or_text(text: str):
    """A bare number is in SI (m), as everywhere in a study; else a quantity with a unit."""
    try:
        return float(text)
    except ValueError:
        return text


def _check_reduced_keys(v: dict[str, dict[str, Any]]) -> None:
    """Cross-key checks of the ``reduced`` and ``excitation`` sections."""
    labels = reduced_mode_labels(v["reduced"]["modes"], v["disc"]["motion"])
    orders = [int(label[3:-1]) for label in labels if label != "P1"]
    rings = v["reduced"]["rings"]
    if orders and max(orders) > rings - 1:
        raise _fail("reduced.rings", rings, f">= {max(orders) + 1}",
                    f"(0,{max(orders)}) needs at least {max(orders) + 1} rings")
    x = v["excitation"]
    if x["f_end"] <= x["f_start"]:
        raise _fail("excitation.f_end", x["f_end"], f"> excitation.f_start = {x['f_start']:g} Hz")
    nyquist = 0.5 / x["sample_time"]
    if x["f_end"] > nyquist:
        raise _fail("excitation.f_end", x["f_end"], f"<= {nyquist:g} Hz = 1 / (2 "
                    "excitation.sample_time)", "above the Nyquist frequency")
    samples = x["duration"] / x["sample_time"]
    if abs(samples - round(samples)) > 1e-6 * samples or not 4 <= round(samples) <= 10_000_000:
        raise _fail("excitation.duration", x["duration"], "an integer multiple (4 to 1e7) of "
                    f"excitation.sample_time = {x['sample_time']:g} s")
    if x["f_end"] * x["duration"] < 1:
        raise _fail("excitation.f_end", x["f_end"], f">= {1 / x['duration']:g} Hz = "
                    "1 / excitation.duration", "no spectral line in the band")


if __name__ == "__main__":
    print(reference_table())
