"""The surrogate's tabulation: a candidate's modes over its parameters, interpolated.

Speed: each candidate's per-condition mode frequencies and quality factors
are tabulated exactly on a coarse parameter grid (9 points for the effects
that need a new static solve, 17 otherwise, 9 x 9 for two parameters) and
interpolated by cubic splines in the (log) parameters (error in ln f below
1e-3, a test checks it, against sigma_f = 1-2 %); fits, folds and the
prequential scores work on the interpolated modes; the in-sample deviance of
every candidate and everything reported of the accepted model are exact.

Parameters are mapped to u in [0, 1] (log or linear between the catalogue's
bounds).  Mode lists that change with a parameter (a mode crossing the
engine's cut-off) keep the labels every evaluable grid point has, so a score
never turns non-finite because a mode far from the band came or went.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import scipy.interpolate
import scipy.optimize

from copdea_fem.diagnosis.effect_record import Parameter
from copdea_fem.diagnosis.effects import CATALOGUE
from copdea_fem.diagnosis.ring_predictor import safe_predict

INVALID = math.inf


def extend_state(state, group, values) -> tuple:
    """``state`` + the effects of ``group`` with ``values`` (in the order of their parameters)."""
    out, offset = list(state), 0
    for effect_id in group:
        count = len(CATALOGUE[effect_id].parameters)
        out.append((effect_id, tuple(float(v) for v in values[offset:offset + count])))
        offset += count
    return tuple(out)


class Tabulation:
    """Per-condition modes of a candidate on a coarse parameter grid, interpolated anywhere.

    Parameters are mapped to u in [0, 1] (log or linear between the bounds).  ``scorer``
    (:class:`copdea_fem.diagnosis.scoring.Scorer`) gives the engine, the conditions and
    the deviance of modes matched to a condition's peaks.
    """

    def __init__(self, scorer, state, group, parameters: list[Parameter],
                 nuisance: bool = False, pinned=(), grid: int | None = None):
        self.scorer = scorer
        self.state, self.group = state, tuple(group)
        # ``pinned``: study keys the engine does not read (held at their defaults, not
        # fitted); ``grid``: points per parameter axis (default 9 or 17, module notes)
        self.pinned = tuple(pinned)
        self.group_parameters = [p for e in self.group for p in CATALOGUE[e].parameters]
        self.parameters = [p for p in parameters if p.key not in self.pinned]
        self.k = len(self.parameters)
        parameters = self.parameters
        expensive = any(CATALOGUE[e].changes_prestress for e in group)   # a new static solve
        count = grid or ((9 if expensive else 17) if self.k == 1 else 9)
        self.axes = [np.linspace(0, 1, count) for _ in range(self.k)]
        self.default_u = np.array([self._to_u(p, p.default) for p in parameters])
        self.cache: dict = {}
        self.splines: dict = {}
        # nuisance: the fitted parameters of the effects already in the state
        self.nuisance = [(i, j, p) for i, (e, values) in enumerate(state) if nuisance
                         for j, p in enumerate(CATALOGUE[e].parameters)
                         if p.key not in self.pinned]
        self.nuisance_u0 = np.array([self._to_u(p, state[i][1][j])
                                     for i, j, p in self.nuisance])
        self.jacobian: dict = {}
        if self.k:
            self._tabulate()
        if self.nuisance:
            self._linearise()

    @property
    def dimension(self) -> int:
        return self.k + len(self.nuisance)

    def state_at(self, u) -> tuple:
        """The full effect state at a point (candidate + nuisance parameters)."""
        u = np.atleast_1d(np.asarray(u, float))
        state = [list(entry) for entry in self.state]
        for (i, j, p), x in zip(self.nuisance, u[self.k:]):
            values = list(state[i][1])
            values[j] = self._from_u(p, x)
            state[i][1] = tuple(values)
        base = tuple((e, tuple(v)) for e, v in state)
        return extend_state(base, self.group, self.values(u[:self.k]))

    def _linearise(self):
        """d ln f / d u_nuisance of every mode at the candidate's default, per condition
        (the modes present at the centre and at every shifted point)."""
        u0 = np.concatenate([self.default_u, self.nuisance_u0])
        step = 0.02
        points = [u0]
        for n in range(len(self.nuisance)):
            u = u0.copy()
            u[self.k + n] += step if u[self.k + n] + step <= 1 else -step
            points.append(u)
        self.scorer.engine.prefetch([(c, self.state_at(u)) for c in self.scorer.conditions
                                for u in points])
        for c in self.scorer.conditions:
            centre = safe_predict(self.scorer.engine, c, self.state_at(u0))
            columns = []
            for n in range(len(self.nuisance)):
                u = u0.copy()
                u[self.k + n] += step if u[self.k + n] + step <= 1 else -step
                shifted = safe_predict(self.scorer.engine, c, self.state_at(u))
                if centre is None or shifted is None:
                    columns = None
                    break
                moved = {m.label: m.frequency_hz for m in shifted.modes}
                columns.append({m.label: math.log(moved[m.label] / m.frequency_hz)
                                / (u[self.k + n] - u0[self.k + n])
                                for m in centre.modes if m.label in moved})
            if columns is None:
                self.jacobian[c.name] = None
                continue
            self.jacobian[c.name] = {m.label: np.array([column[m.label] for column in columns])
                                     for m in centre.modes
                                     if all(m.label in column for column in columns)}

    # parameter <-> u
    @staticmethod
    def _to_u(p: Parameter, value: float) -> float:
        if p.log:
            return math.log(value / p.lower) / math.log(p.upper / p.lower)
        return (value - p.lower) / (p.upper - p.lower)

    @staticmethod
    def _from_u(p: Parameter, x: float) -> float:
        x = float(np.clip(x, 0, 1))
        return p.lower * (p.upper / p.lower) ** x if p.log else p.lower + x * (p.upper - p.lower)

    def values(self, u) -> list:
        """Candidate parameter values (SI) at a point: every parameter of the group, the
        pinned ones at their defaults."""
        free = iter(np.atleast_1d(u)[:self.k])
        return [p.default if p.key in self.pinned else self._from_u(p, next(free))
                for p in self.group_parameters]

    def _tabulate(self):
        grid = np.array(np.meshgrid(*self.axes, indexing="ij")).reshape(self.k, -1).T
        shape = tuple(a.size for a in self.axes)
        self.scorer.engine.prefetch([(c, extend_state(self.state, self.group, self.values(u)))
                                for c in self.scorer.conditions for u in grid])
        for c in self.scorer.conditions:
            predictions = [safe_predict(self.scorer.engine, c, extend_state(self.state, self.group,
                                                                  self.values(u)))
                           for u in grid]
            valid = [p for p in predictions if p is not None]
            if not valid:
                self.splines[c.name] = None
                continue
            # labels every evaluable point has; the others (a mode crossing the engine's
            # cut-off, a pumping root that comes and goes) are interpolated where they exist
            common = set.intersection(*({m.label for m in p.modes} for p in valid))
            template = [m for m in valid[len(valid) // 2].modes if m.label in common]
            ok = np.array([p is not None for p in predictions])
            freq = np.full((grid.shape[0], len(template)), np.nan)
            quality = np.full_like(freq, np.nan)
            partial: dict = {}
            for g, p in enumerate(predictions):
                if ok[g]:
                    modes = {m.label: m for m in p.modes}
                    picked = [modes[m.label] for m in template]
                    freq[g] = [math.log(m.frequency_hz) for m in picked]
                    quality[g] = [math.log(m.quality_factor) if 0 < m.quality_factor < math.inf
                                  else np.nan for m in picked]
                    for m in p.modes:
                        if m.label not in common:
                            partial.setdefault(m.label, []).append((grid[g], m))
            self.splines[c.name] = ModeInterpolator(self.axes, shape, ok, freq, quality,
                                                     template, partial)

    def modes_at(self, name, u):
        u = np.atleast_1d(np.asarray(u, float))
        if self.k:
            spline = self.splines.get(name)
            if spline is None:
                return None
            modes = spline(u[:self.k])
        else:
            modes = self._fixed_modes(name)
        if modes is None or not self.nuisance:
            return modes
        jacobian = self.jacobian.get(name)
        if jacobian is None or u.size == self.k:
            return modes
        shift = u[self.k:] - self.nuisance_u0
        out = []
        for m in modes:
            row = jacobian.get(m.label)
            factor = math.exp(float(row @ shift)) if row is not None else 1.0
            out.append(replace(m, frequency_hz=m.frequency_hz * factor))
        return out

    def _fixed_modes(self, name):
        if not hasattr(self, "_fixed"):
            self._fixed = {}
            state = extend_state(self.state, self.group, self.values([]))
            self.scorer.engine.prefetch([(c, state) for c in self.scorer.conditions])
            for c in self.scorer.conditions:
                p = safe_predict(self.scorer.engine, c,
                                 extend_state(self.state, self.group, self.values([])))
                self._fixed[c.name] = list(p.modes) if p is not None else None
        return self._fixed.get(name)

    def deviance(self, names, u) -> float:
        """Deviance of the named conditions at u (candidate [+ nuisance] parameters)."""
        total = 0.0
        for c in self.scorer.conditions:
            if c.name not in names:
                continue
            modes = self.modes_at(c.name, u)
            if modes is None:
                return INVALID
            total += self.scorer.match(c, modes).deviance
        return total

    def profile(self, names, candidate_u) -> tuple[float, np.ndarray]:
        """Deviance with the nuisance parameters profiled out, and the full u.

        ln f is linear in the nuisance parameters (:meth:`_linearise`), so for the
        pairs within the strict gate (the Gaussian branch of the deviance) their best
        shift is a least-squares solution; two Gauss-Newton passes with re-matching,
        kept only where they lower the deviance.
        """
        candidate_u = np.atleast_1d(np.asarray(candidate_u, float))[:self.k]
        best_u = np.concatenate([candidate_u, self.nuisance_u0])
        best = self.deviance(names, best_u)
        if not self.nuisance or not math.isfinite(best):
            return best, best_u
        u = best_u.copy()
        for _ in range(2):
            rows, residuals = [], []
            for c in self.scorer.conditions:
                if c.name not in names or self.jacobian.get(c.name) is None:
                    continue
                modes = self.modes_at(c.name, u)
                match = self.scorer.match(c, modes)
                limit = self.scorer.terms(c.name).strict_gate()
                for pair in match.pairs:
                    row = self.jacobian[c.name].get(pair.model.label)
                    if row is not None and abs(pair.log_error) <= limit:
                        rows.append(row)
                        residuals.append(pair.log_error)
            if len(rows) < len(self.nuisance):
                break
            step = np.linalg.lstsq(np.array(rows), np.array(residuals), rcond=None)[0]
            u = u.copy()
            u[self.k:] = np.clip(u[self.k:] + step, 0, 1)
            value = self.deviance(names, u)
            if value < best:
                best, best_u = value, u.copy()
            else:
                break
        return best, best_u

    def start(self) -> np.ndarray:
        """The physical defaults of the candidate, the current nuisance values (u)."""
        return np.concatenate([self.default_u, self.nuisance_u0])

    def check_interpolation(self, name) -> float:
        """Largest |ln f| error of the interpolation against exact predictions, at the
        midpoints of the coarse grid (for tests)."""
        condition = next(c for c in self.scorer.conditions if c.name == name)
        worst = 0.0
        if self.k != 1:
            return worst
        axis = self.axes[0]
        for x in 0.5 * (axis[1:] + axis[:-1]):
            u = np.concatenate([[x], self.nuisance_u0])
            exact = safe_predict(self.scorer.engine, condition, self.state_at(u))
            modes = self.modes_at(name, u)
            if exact is None or modes is None:
                continue
            exact_by_label = {m.label: m.frequency_hz for m in exact.modes}
            for b in modes:
                if b.label in exact_by_label:
                    worst = max(worst, abs(math.log(exact_by_label[b.label] / b.frequency_hz)))
        return worst

    def fit(self, names) -> np.ndarray:
        """u minimising the interpolated deviance of the named conditions (candidate
        parameters, then the nuisance ones)."""
        key = tuple(sorted(names))
        if key in self.cache:
            return self.cache[key]
        if not self.k:
            _, u = self.profile(names, [])
            self.cache[key] = u
            return u
        fine = 61 if self.k == 1 else 13
        axes = [np.linspace(0, 1, fine) for _ in range(self.k)]
        points = np.array(np.meshgrid(*axes, indexing="ij")).reshape(self.k, -1).T
        per_condition = self._fine_table(points)
        total = sum(per_condition[n] for n in names)
        start = points[int(np.argmin(total))]
        objective = lambda x: min(self.profile(names, np.clip(x, 0, 1))[0], 1e12)  # noqa
        step = 1.0 / (fine - 1)
        reach = 3 * step if self.nuisance else step   # the nuisance can move the optimum
        if self.k == 1:
            low, high = max(0.0, start[0] - reach), min(1.0, start[0] + reach)
            found = scipy.optimize.minimize_scalar(lambda x: objective([x]), bounds=(low, high),
                                                   method="bounded",
                                                   options={"xatol": 1e-4})
            best = np.array([found.x]) if found.fun <= objective(start) else start
        else:   # two parameters: simplex with the nuisance held, profiled at the end
            held = lambda x: min(self.deviance(names, np.clip(x, 0, 1)), 1e12)  # noqa: E731
            simplex = np.array([start, start + [step, 0], start + [0, step]])
            found = scipy.optimize.minimize(held, start, method="Nelder-Mead",
                                            options={"initial_simplex": simplex,
                                                     "xatol": 1e-3, "fatol": 1e-2,
                                                     "maxfev": 60})
            best = np.clip(found.x, 0, 1) if found.fun <= held(start) else start
        _, u = self.profile(names, best)
        self.cache[key] = u
        return u

    def _fine_table(self, points) -> dict:
        if hasattr(self, "_fine"):
            return self._fine
        table = {}
        for c in self.scorer.conditions:
            table[c.name] = np.array([self.deviance([c.name], u) for u in points])
        self._fine = table
        return table


class ModeInterpolator:
    """Cubic interpolation of ln f and ln Q of every mode over the coarse grid (one spline
    object for the modes every point has; a Q that is not finite everywhere keeps its
    template value).  ``partial``: ``{label: [(u, mode), ...]}`` of modes only some points
    have; with one parameter each is interpolated (ln f, linearly) over the range where it
    exists and is absent outside it; with two they are left out."""

    def __init__(self, axes, shape, ok, freq, quality, template, partial=None):
        self.template = template
        self.k = len(axes)
        self.has_q = np.all(np.isfinite(quality[ok]), axis=0) if np.any(ok) else \
            np.zeros(freq.shape[1], bool)
        quality = np.where(self.has_q, quality, 0.0)
        values = np.concatenate([freq, quality], axis=1)
        self.low, self.high, self.spline = 1.0, 0.0, None
        self.partial = []
        if self.k == 1:
            x = axes[0][ok]
            if x.size >= 2:
                self.low, self.high = x.min(), x.max()
                self.spline = (scipy.interpolate.CubicSpline(x, values[ok], axis=0)
                               if x.size >= 4 else scipy.interpolate.interp1d(
                                   x, values[ok], axis=0))
            for points in (partial or {}).values():
                u = np.array([point[0][0] for point in points])
                ln_f = np.array([math.log(mode.frequency_hz) for _, mode in points])
                self.partial.append((u.min(), u.max(), u, ln_f, points[len(points) // 2][1]))
        elif np.all(ok):
            self.low, self.high = 0.0, 1.0
            self.spline = [scipy.interpolate.RectBivariateSpline(*axes,
                                                                 values[:, j].reshape(shape))
                           for j in range(values.shape[1])]

    def __call__(self, u):
        if self.spline is None or not all(self.low - 1e-12 <= x <= self.high + 1e-12
                                          for x in u[:self.k]):
            return None
        if self.k == 1:
            values = np.asarray(self.spline(u[0]))
        else:
            values = np.array([s(u[0], u[1])[0, 0] for s in self.spline])
        count = len(self.template)
        out = []
        for j, mode in enumerate(self.template):
            ln_f, ln_q = values[j], values[count + j]
            if not math.isfinite(ln_f):
                return None
            quality = math.exp(ln_q) if self.has_q[j] else mode.quality_factor
            out.append(replace(mode, frequency_hz=math.exp(ln_f), quality_factor=quality))
        for low, high, x, ln_f, mode in self.partial:
            if low - 1e-12 <= u[0] <= high + 1e-12:
                frequency = math.exp(float(np.interp(u[0], x, ln_f)))
                out.append(replace(mode, frequency_hz=frequency))
        return sorted(out, key=lambda m: m.frequency_hz)
