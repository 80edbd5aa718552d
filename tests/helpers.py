"""Helpers the tests share: coarse studies and closed forms (no test module imports another)."""

import math

import numpy as np
from scipy.optimize import brentq
from scipy.special import jn_zeros, jv, yv

from copdea_fem.fe import engine_for
from copdea_fem.fe.materials import Membrane
from copdea_fem.study import parse_study

# coarsest sensible: 9 mm membrane mesh (two elements across G1's 18.5 mm width),
# pressure order 1 (order 2 in the PML), air elements up to r_o
COARSE_AIR = {"membrane_size": "9 mm", "order": 2, "pressure_order": 1, "air_size": "35.5 mm"}


def coupled_study(**sections):
    raw = {"air": {"enabled": True}, "mesh": dict(COARSE_AIR), "load": {"voltage": "2 kV"}}
    for section, values in sections.items():
        raw.setdefault(section, {}).update(values)
    return parse_study(raw, name="coupled-test")


def on_its_engine(solve, study, **keywords):
    """``solve(study, engine=<the study's engine>, **keywords)``: the FE pipeline's functions
    take the engine their caller resolved (:func:`copdea_fem.fe.engine_for`), as the API
    resolves it once per call."""
    return solve(study, engine=engine_for(study), **keywords)


def annulus_roots(m: int, a: float, b: float, k_max: float) -> list[float]:
    """Wavenumbers k [1/m] with J_m(ka) Y_m(kb) - J_m(kb) Y_m(ka) = 0 (fixed rims)."""
    if a == 0:
        return list(jn_zeros(m, 40)[jn_zeros(m, 40) < k_max * b] / b)
    cross = lambda k: jv(m, k * a) * yv(m, k * b) - jv(m, k * b) * yv(m, k * a)
    grid = np.linspace(1e-3 / b, k_max, 40000)
    values = cross(grid)
    return [brentq(cross, grid[i], grid[i + 1])
            for i in np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))]


def bessel_frequency(study, m, n) -> float:
    material = Membrane.from_study(study)
    speed = math.sqrt(material.equibiaxial_tension(study.load.voltage)
                      / material.areal_density)       # m/s, c = sqrt(T / (rho h))
    a, b = study.geometry.inner_radius, study.geometry.outer_radius
    k_max = 2 * math.pi * 1.5 * study.eigen.f_max / speed
    return annulus_roots(m, a, b, k_max)[n - 1] * speed / (2 * math.pi)
