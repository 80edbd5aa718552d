"""Fit the Mooney-Rivlin coefficients of eq. (20) to force-displacement data (Sect. 5.1, Fig. 4b).

The paper fitted c10, c20, c01 "on the tensile curves ... using a static
version of the model presented in Sect. 3.2.1": that is what this does.  The
model force is the ring model's static disc force F(z; V, c) (eq. 10 without
inertia); the fit minimises sum (F_model - F_measured)^2 (equal weights: a
force sensor's noise does not scale with the force) over c = (c10, c20, c01).

Jacobian, exact: Psi_m is linear in c (eq. 20), Psi_m = sum_i c_i psi_i with
psi_1 = I1 - 3, psi_2 = (I1 - 3)^2, psi_3 = I_{-1} - 3, so the energy's
derivative in c_i is the elastic gradient of a membrane with c_i = 1 and the
other two 0.  At equilibrium (dPi/dq_int = 0, disc held at z),

    dF/dc_i = G_i,disc - K_disc,int K_int,int^-1 G_i,int,

G_i = d/dq of the basis energy, K the Hessian of Pi (implicit function theorem).

Identifiability: see :func:`fit_material` (one pre-stretch pins c10 + lambda_p^2
c01, not each).

Uncertainty: the usual linearised estimate, covariance = s^2 (J^T W J)^-1 with
s^2 = weighted SSR / (N - 3) (W = 1/sigma^2: the noise level is taken from the
scatter itself); standard errors are its diagonal's square roots.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from copdea_fem.fe.materials import Membrane
from copdea_fem.reduced.rings import ReducedModelError, RingModel

PARAMETERS = ("c10", "c20", "c01")
_SCALE = 1e5  # Pa: the size of c10 (Sect. 5.1), so the fitted unknowns are O(1)


@dataclass(frozen=True)
class MaterialFit:
    """Least-squares estimate of (c10, c20, c01) [Pa] of eq. (20).

    Attributes
    ----------
    values : ndarray
        c10, c20, c01 [Pa].
    covariance : ndarray, shape (3, 3)
        [Pa^2].
    residual_rms : float
        sqrt(SSR / N) of the force residuals [N].
    point_count : int
    """

    values: np.ndarray
    covariance: np.ndarray
    residual_rms: float
    point_count: int

    @property
    def standard_error(self) -> np.ndarray:
        """sqrt(diag(covariance)) [Pa]."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def correlation(self) -> np.ndarray:
        s = self.standard_error
        return self.covariance / np.outer(s, s)

    def as_dict(self) -> dict:
        return dict(zip(PARAMETERS, map(float, self.values)))

    def membrane(self, base: Membrane) -> Membrane:
        return replace(base, **self.as_dict())


class _ForceModel:
    """F(z; V, c) and dF/dc at a list of data points, with warm starts between calls."""

    def __init__(self, model: RingModel, z, voltage):
        self.model = model
        self.z = np.asarray(z, float)
        self.voltage = np.asarray(voltage, float)
        # solve each voltage's points in increasing z, each from the previous one
        self.order = np.lexsort((np.abs(self.z), self.voltage))
        self.states = {}
        base = model.membrane
        self.basis = [replace(base, c10=1.0, c20=0.0, c01=0.0),
                      replace(base, c10=0.0, c20=1.0, c01=0.0),
                      replace(base, c10=0.0, c20=0.0, c01=1.0)]

    def evaluate(self, coefficients):
        membrane = replace(self.model.membrane, **dict(zip(PARAMETERS, map(float, coefficients))))
        model = self.model.with_membrane(membrane)
        force = np.empty(self.z.size)
        jacobian = np.empty((self.z.size, 3))
        interior, disc = model.interior_dofs, model.disc_dof
        previous, previous_voltage = None, None
        for index in self.order:
            start = self.states.get(index)
            if start is None and previous is not None and previous_voltage == self.voltage[index]:
                start = previous
            eq = model.equilibrium(self.z[index], self.voltage[index], start=start)
            self.states[index] = previous = (eq.radii, eq.heights)
            previous_voltage = self.voltage[index]
            force[index] = eq.disc_force
            _, hess = model.potential_derivatives(eq.radii, eq.heights, eq.voltage)
            k_ii = hess[np.ix_(interior, interior)]
            k_di = hess[disc, interior]
            for i, basis in enumerate(self.basis):
                g, _ = model.elastic_derivatives(eq.radii, eq.heights, membrane=basis,
                                                 hessian=False)
                jacobian[index, i] = g[disc] - k_di @ np.linalg.solve(k_ii, g[interior])
        return force, jacobian


def fit_material(model: RingModel, z, force, voltage, prestretch=None, inner_radius=None,
                 force_std=None, initial=None) -> MaterialFit:
    """Least-squares c10, c20, c01 from measured disc force F(z) at voltages V.

    Parameters
    ----------
    model : RingModel
        Geometry, ring count and the other film data (h0, eps, rho0).
    z, force, voltage : array_like
        Disc displacement [m], measured force [N] and voltage [V] per point.
    prestretch, inner_radius : array_like, optional
        Per-point lambda_p [-] and r_i [m] when the data come from several
        samples; default: the model's.
    force_std : array_like, optional
        Per-point standard deviation of the measured force [N]; residuals are
        weighted by its inverse (weighted least squares).  Default: equal
        weights (a force sensor whose noise does not scale with the force).
    initial : sequence of 3 floats, optional
        Start values [Pa]; default: the model membrane's coefficients.

    Notes
    -----
    On one sample, c10 and c01 are nearly inseparable: the meridian stress is
    sigma_1 = 2 (l1^2 - l3^2)(dPsi/dI1 + l2^2 c01), and the hoop stretch l2
    stays close to lambda_p across a COP-DEA, so F(z) fixes mostly
    c10 + lambda_p^2 c01 (correlation ~ -1; the standard errors say so).
    Samples at two pre-stretches separate them.

    Raises
    ------
    ReducedModelError
        Fewer than 4 points, non-finite data, or a singular Jacobian.
    """
    z, force, voltage = (np.asarray(a, float).ravel() for a in (z, force, voltage))
    if not (z.size == force.size == voltage.size) or z.size < 4:
        raise ReducedModelError(f"{z.size} force-displacement points are not allowed; allowed: "
                                ">= 4 points, each with z, force and voltage")
    lam = np.full(z.size, model.membrane.prestretch) if prestretch is None else (
        np.asarray(prestretch, float).ravel())
    r_in = np.full(z.size, model.inner_radius) if inner_radius is None else (
        np.asarray(inner_radius, float).ravel())
    sigma = np.ones(z.size) if force_std is None else np.asarray(force_std, float).ravel()
    columns = (z, force, voltage, lam, r_in, sigma)
    if (lam.size != z.size or r_in.size != z.size or sigma.size != z.size
            or not all(np.all(np.isfinite(c)) for c in columns) or np.any(sigma <= 0)):
        raise ReducedModelError("force-displacement data with NaN/inf or ragged columns are not "
                                "allowed; allowed: finite numbers, one of each per point, "
                                "force_std > 0")
    groups = []
    for sample in sorted(set(zip(lam.tolist(), r_in.tolist()))):
        rows = np.flatnonzero((lam == sample[0]) & (r_in == sample[1]))
        sample_model = replace(model, inner_radius=sample[1],
                               membrane=replace(model.membrane, prestretch=sample[0]))
        groups.append((rows, _ForceModel(sample_model, z[rows], voltage[rows])))
    m = model.membrane
    start = np.asarray(initial if initial is not None else (m.c10, m.c20, m.c01), float) / _SCALE
    cache = {}

    def evaluate(x):
        key = tuple(x)
        if key not in cache:
            cache.clear()
            values, jacobian = np.empty(z.size), np.empty((z.size, 3))
            for rows, forces in groups:
                values[rows], jacobian[rows] = forces.evaluate(x * _SCALE)
            cache[key] = values, jacobian
        return cache[key]

    import scipy.optimize  # at use: 0.15 s of import the modal commands skip
    result = scipy.optimize.least_squares(
        lambda x: (evaluate(x)[0] - force) / sigma, start,
        jac=lambda x: evaluate(x)[1] * (_SCALE / sigma[:, None]),
        method="trf", bounds=([1e-6, -np.inf, -np.inf], np.inf), x_scale="jac",
        ftol=1e-12, xtol=1e-12, gtol=1e-12)
    values = result.x * _SCALE
    model_force, jacobian = evaluate(result.x)
    weighted = (model_force - force) / sigma
    jacobian = jacobian / sigma[:, None]
    ssr = float(weighted @ weighted)
    dof = max(z.size - 3, 1)
    jtj = jacobian.T @ jacobian
    if np.linalg.cond(jtj) > 1e14:  # beyond double precision: the three are not separable
        raise ReducedModelError("the force-displacement data cannot separate c10, c20 and c01 "
                                "(singular Jacobian); allowed: data over a range of z, ideally "
                                "from samples at two pre-stretches")
    covariance = ssr / dof * np.linalg.inv(jtj)
    return MaterialFit(values=values, covariance=covariance,
                       residual_rms=float(np.sqrt(np.mean((model_force - force) ** 2))),
                       point_count=int(z.size))
