"""The FE model of record of the diagnosis (issue 13): study -> structural modes, cached.

The diagnosis compares the measurement with the finite-element model as the
base study is written: in vacuo where ``air.enabled`` is false, fully coupled
with the air (and its frame) where it is true.  :func:`fe_study` maps a
diagnosis study to the study the FE runs; :class:`FEModel` solves it with the
engine the geometry allows (the axisymmetric-harmonic engine for dry modes and
for frames none/baffle/circle, ~1-2 s; the 3-D quadrant for the square frame)
and keeps the structural modes (out-of-plane and pumping) in memory and,
optionally, on disk, keyed by a hash of the FE study.

What the FE honours (:data:`FE_EFFECT_KEYS`): everything of the geometry,
material and load, ``air.enabled``, ``geometry.frame``, ``disc.motion`` and
the spring's stiffness, and the two effect keys ``effects.stiffness_scale``
and ``effects.maxwell_scale`` (:meth:`copdea_fem.materials.Membrane.with_effects`).
What it does not: the ring model's own keys (``reduced.*``), the air-mass
estimate and its scale, visco-elasticity, the spring's mass, modal damping --
those act through the anchored ring surrogate (:mod:`copdea_fem.diagnose.anchored`).

Modes.  Frequencies are the real parts of the (coupled) eigenfrequencies [Hz].
A split pair ``(m,n)a``/``(m,n)b`` that a vibrometer cannot resolve (relative
split below :data:`PAIR_MERGE`) is one mode ``(m,n)`` at the mean frequency;
in-plane modes (hardly seen by an out-of-plane vibrometer) and air modes are
left out.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

from copdea_fem.study import Study

FE_CACHE_VERSION = 1           # bump when the FE's numbers change for the same study
PAIR_MERGE = 2e-3              # split pairs closer than this (relative) are one peak: a
                               # fifth of a 1 % identification scatter, not resolvable

FE_EFFECT_KEYS = ("effects.stiffness_scale", "effects.maxwell_scale")
# The FE's band reaches past the data's, so a mode just above the band edge is still
# paired: 25 % is past the 4 sigma_f strict gate of unknown-kind peaks and near the 50 %
# gate of known ones (copdea_fem.diagnose.compare), at the cost of more FE modes.
BAND_MARGIN = 1.25


@dataclass(frozen=True)
class FEMode:
    """One structural mode of the FE: label ``P1``, ``(0,n)``, ``(m,n)`` (or ``(m,n)a/b``),
    kind ``pumping``/``axisymmetric``/``non-axisymmetric``, frequency [Hz], damping ratio
    Im f / |f| [-] (0 in vacuo)."""

    label: str
    kind: str
    frequency_hz: float
    damping_ratio: float = 0.0


@dataclass(frozen=True)
class FEResult:
    """The structural modes of one FE study, and how they were obtained."""

    modes: tuple
    engine: str                  # "axisymmetric" or "3d"
    coupled: bool
    seconds: float
    key: str

    def frequencies(self) -> dict:
        return {m.label: m.frequency_hz for m in self.modes}


def fe_study(study: Study, f_max: float | None = None) -> Study:
    """The study the FE solves for a diagnosis study.

    In vacuo the frame plays no part (it is a reflector in the air), so dry modes run
    on the axisymmetric engine with ``frame: none``; coupled ones keep the frame and
    let ``mesh.engine: auto`` choose.  ``f_max`` [Hz] (default: the study's) is the
    top of the FE band; no result files are written.
    """
    overrides = {"output.plots": False, "output.paraview": False}
    if f_max is not None:
        overrides["eigen.f_max"] = float(f_max)
    if not study["air"]["enabled"]:
        overrides.update({"geometry.frame": "none", "mesh.engine": "axisymmetric"})
    return study.replace(overrides)


def fe_key(study: Study) -> str:
    """Hash of what the FE reads from a study (:func:`fe_study` applied) and
    :data:`FE_CACHE_VERSION`: the cache key of :class:`FEModel`.  Sections of the
    physics and the mesh, whole; of the others only the keys that change the modes."""
    whole = ("geometry", "membrane", "disc", "load", "air", "mesh")
    picked = ("spring.stiffness", "eigen.f_min", "eigen.f_max", "eigen.max_damping_ratio",
              "air.min_membrane_energy") + FE_EFFECT_KEYS
    items = {f"{s}.{k}": v for s in whole for k, v in study[s].items()}
    items.update({key: study.get(key) for key in picked})
    for key in ("membrane.rayleigh_alpha", "membrane.rayleigh_beta", "membrane.prony"):
        if not items.get(key):          # undamped (the default): the keys of before issue 23
            items.pop(key, None)
    text = json.dumps({"version": FE_CACHE_VERSION, "study": items}, sort_keys=True,
                      default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def structural_modes(modes) -> tuple:
    """:class:`FEMode` list from the pipeline's modes (module notes: pairs merged)."""
    kept = []
    for mode in modes:
        if mode.kind not in ("out-of-plane", "pumping") or not mode.label:
            continue
        magnitude = math.hypot(mode.freq_hz, getattr(mode, "freq_im_hz", 0.0))
        zeta = abs(getattr(mode, "freq_im_hz", 0.0)) / magnitude if magnitude else 0.0
        kind = ("pumping" if mode.kind == "pumping" else
                "axisymmetric" if mode.m == 0 else "non-axisymmetric")
        kept.append(FEMode(mode.label, kind, float(mode.freq_hz), float(zeta)))
    by_label = {m.label: m for m in kept}
    out = []
    for mode in kept:
        if mode.label.endswith("b") and mode.label[:-1] + "a" in by_label:
            continue
        if mode.label.endswith("a") and mode.label[:-1] + "b" in by_label:
            other = by_label[mode.label[:-1] + "b"]
            if abs(other.frequency_hz / mode.frequency_hz - 1) < PAIR_MERGE:
                out.append(FEMode(mode.label[:-1], mode.kind,
                                  0.5 * (mode.frequency_hz + other.frequency_hz),
                                  0.5 * (mode.damping_ratio + other.damping_ratio)))
                continue
            out.append(other)
        out.append(mode)
    return tuple(sorted(out, key=lambda m: m.frequency_hz))


CACHE_VARIABLE = "COPDEA_FEM_FE_CACHE"


def fe_cache_dir() -> Path:
    """``$COPDEA_FEM_FE_CACHE`` when set, else the user cache folder (``platformdirs``:
    ``~/.cache/copdea-fem/fe-modes`` on Linux)."""
    if os.environ.get(CACHE_VARIABLE):
        return Path(os.environ[CACHE_VARIABLE]).expanduser()
    import platformdirs
    return Path(platformdirs.user_cache_dir("copdea-fem")) / "fe-modes"


class FEModel:
    """FE structural modes of diagnosis studies, solved once per FE study.

    Parameters
    ----------
    cache_dir : path, optional
        Folder of ``<key>.json`` files kept between runs (default
        :func:`fe_cache_dir`); ``False``: memory only.
    progress : callable, optional
    """

    def __init__(self, cache_dir=None, progress=None):
        if cache_dir is None:
            cache_dir = fe_cache_dir()
        self.cache_dir = Path(cache_dir) if cache_dir else None
        self.progress = progress or (lambda message: None)
        self._memory: dict = {}
        self.solves = 0
        self.seconds = 0.0

    def modes(self, study: Study, f_max: float | None = None) -> FEResult:
        """Structural modes of ``study`` (a diagnosis study: :func:`fe_study` applied)."""
        run = fe_study(study, f_max)
        key = fe_key(run)
        hit = self._memory.get(key) or self._read(key)
        if hit is not None:
            self._memory[key] = hit
            return hit
        result = self._solve(run, key)
        self._memory[key] = result
        self._write(result)
        return result

    def _solve(self, run: Study, key: str) -> FEResult:
        from copdea_fem.solve import coupled_modes, dry_modes
        from copdea_fem.study import engine_of
        coupled = bool(run["air"]["enabled"])
        load = run["load"]
        self.progress(f"FE ({engine_of(run)}, {'coupled' if coupled else 'in vacuo'}) at "
                      f"z = {1e3 * load['z']:g} mm, V_b = {1e-3 * load['voltage']:g} kV ...")
        start = time.perf_counter()
        if coupled:
            modes = coupled_modes(run).modes
        else:
            _, modes, _ = dry_modes(run)
        seconds = time.perf_counter() - start
        self.solves += 1
        self.seconds += seconds
        return FEResult(structural_modes(modes), engine_of(run), coupled, seconds, key)

    # -- disk cache ------------------------------------------------------------------------
    def _path(self, key: str):
        return self.cache_dir / f"{key}.json" if self.cache_dir else None

    def _read(self, key: str):
        path = self._path(key)
        if path is None or not path.is_file():
            return None
        try:
            raw = json.loads(path.read_text())
            modes = tuple(FEMode(**m) for m in raw["modes"])
            return FEResult(modes, raw["engine"], raw["coupled"], float(raw["seconds"]), key)
        except (ValueError, KeyError, TypeError):
            return None           # a damaged entry is solved again (and rewritten)

    def _write(self, result: FEResult) -> None:
        path = self._path(result.key)
        if path is None:
            return
        document = {"modes": [m.__dict__ for m in result.modes], "engine": result.engine,
                    "coupled": result.coupled, "seconds": result.seconds}
        staging = path.with_suffix(f".tmp{os.getpid()}")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            staging.write_text(json.dumps(document, indent=1))
            os.replace(staging, path)          # only <key>.json: the names this class makes
        except OSError as error:               # the cache only saves time: never fail on it
            self.progress(f"FE cache {self.cache_dir} not written ({error.strerror or error})")
            staging.unlink(missing_ok=True)
