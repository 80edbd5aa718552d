r"""Synthetic vibrometer exports made by the FE (``copdea-fem synth --format uff``).

The *truth* is the FE of the study with the chosen effects switched on (as the diagnosis
switches them, :func:`copdea_fem.diagnosis.ring_predictor.state_overrides`; solved as the diagnosis
solves its model of record, :func:`copdea_fem.diagnosis.fe.fe_study`); the written
``measured.yaml`` names the study *without* them as its base, so diagnosing it should find
them.  What the export holds, per condition, is what a PSV-type scanning vibrometer exports:

- the scan grid of the paper (Fig. 5d): points on rings of the membrane and a few on the
  disc (default 5 rings x 16 = 80 on the membrane, 4 on the disc), at their places on the
  *prestressed* device (:meth:`copdea_fem.fe.engines.Engine.prestressed_positions`),
  three velocity components each;
- FRFs of velocity per volt of drive made by the FE forced response
  (:func:`copdea_fem.forced_response.scan.scan_response`: the modal path of
  :mod:`copdea_fem.fe.forced.harmonic` with its static correction, standard
  ``e^{+i omega t}`` convention, mobility) of an *imperfect electrode*
  (:class:`copdea_fem.fe.forced.electrode.ElectrodeImperfection`): a drive weight
  ``1 + sum_m delta_m cos(m (theta - theta_m))`` on the co-energy, ``delta_m =
  imperfection x LogNormal(0, 1/2)`` and ``theta_m`` at random for every order m >= 1 of the
  band's modes, so that the non-axisymmetric modes light up as they do in the paper's scans
  (Fig. 7) - each by the forcing of its own order, the in-plane ones included; every
  structural mode damped by the paper's modal b/m (eq. 19) for a damping ratio
  ``damping_ratio`` of its membrane share (material loss; the FE in vacuo has none), the
  radiation by the coupled pencil itself;
- frequency scatter: each mode's eigenvalue moved by ``exp(2 N(0, frequency_noise))`` (its
  frequency by ``exp(N(0, frequency_noise))``; the twins of an axisymmetric pair together,
  the members (m,n)a/b of a split pair by one factor: the scatter stands for the model's
  error, which a pair's split - an imperfection's or a frame's - does not share);
- measurement noise: complex Gaussian, ``snr_db`` below the largest |H| of the export.

The export's damping is the base study's own modal damping (``reduced.damping_*``, eq. 19,
:func:`modal_damping`), the identification recovers it (Q within 10 % of the truth's on an
isolated mode), and ``damping_ratio`` adds a damping the model lacks (0 by default).  The
written ``measured.yaml`` still declares the quality factors uninformative
(``noise.quality_relative`` = :data:`QUALITY_UNINFORMATIVE`; a user may edit it): what the
diagnosis is asked to find here is the effects switched on, from frequencies and shapes.
Measured on the vibrometer battery (tests/vibrometer/test_vibrometer_battery.py, seeds 0-19):
uninformative, ``air_loading`` named alone on 20 of 20; with ``quality_relative: 0.25``, on
19 of 20, the other adding a marginal ``uniform_stiffness`` (ln U = 3.30 against 3.12).

The FE is solved on the study's own mesh (coarse studies give coarse truths).
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import yaml

from copdea_fem.diagnosis.synth import MAX_SEED
from copdea_fem.study import Study, StudyError, dump_resolved

logger = logging.getLogger(__name__)

#: ``noise.quality_relative`` of a synthetic set: the bound of
#: :data:`copdea_fem.measured.manifest.NOISE_BOUNDS`, a 1-sigma scatter of ln Q of 5 (a
#: factor e^5): the quality factors carry no weight (module notes).
QUALITY_UNINFORMATIVE = 5.0


@dataclass(frozen=True)
class ScanOptions:
    """The grid, frequency axis and scatter of a synthetic export (module notes).

    Attributes
    ----------
    rings, per_ring, disc_points : int
        Membrane rings, points per ring, points on the disc.
    f_min, f_max, resolution : float
        Frequency axis [Hz]: ``f_min, f_min + resolution, ..., <= f_max``.
    frequency_noise : float
        1-sigma scatter of ln f of each mode [-].
    snr_db : float
        Noise level below the export's largest |H| [dB].
    damping_ratio : float
        A damping ratio [-] added to every structural mode beyond the study's modal damping
        (:func:`modal_damping`: a damping the model lacks).
    imperfection : float
        Scale of the electrode's drive imperfection [-]: ``delta_m = imperfection
        LogNormal(0, 1/2)`` for every order m >= 1 of the band's modes
        (:class:`copdea_fem.fe.forced.electrode.ElectrodeImperfection`).
    seed : int
    """

    rings: int = 5
    per_ring: int = 16
    disc_points: int = 4
    f_min: float = 1.25
    f_max: float = 1000.0
    resolution: float = 1.25
    frequency_noise: float = 0.01
    snr_db: float = 60.0
    damping_ratio: float = 0.0
    imperfection: float = 0.1
    seed: int = 0

    def check(self) -> None:
        """Refuse settings outside their bounds (StudyError naming the option)."""
        integers = {"rings": (1, 50), "per_ring": (3, 360), "disc_points": (0, 100),
                    "seed": (0, MAX_SEED)}
        numbers = {"f_min": (0.0, 1e5), "f_max": (1.0, 1e5), "resolution": (1e-3, 1e3),
                   "frequency_noise": (0.0, 0.2), "snr_db": (0.0, 200.0),
                   "damping_ratio": (0.0, 0.5), "imperfection": (0.0, 1.0)}
        for name, (lo, hi) in integers.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                raise StudyError(f"{name} = {value!r} is not allowed; allowed: an integer in "
                                 f"[{lo}, {hi}]")
        for name, (lo, hi) in numbers.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and lo <= value <= hi):
                raise StudyError(f"{name} = {value!r} is not allowed; allowed: a number in "
                                 f"[{lo:g}, {hi:g}]")
        if not self.f_max > self.f_min + 8 * self.resolution:
            raise StudyError(f"f_max = {self.f_max:g} Hz is not allowed; allowed: above "
                             f"f_min + 8 resolution = {self.f_min + 8 * self.resolution:g} Hz")

    def frequencies(self) -> np.ndarray:
        """The export's frequency axis [Hz]."""
        count = math.floor((self.f_max - self.f_min) / self.resolution + 1e-9) + 1
        return self.f_min + self.resolution * np.arange(count)


def psv_reference_grid(outer_radius: float, inner_radius: float, options: ScanOptions):
    """Reference (flat) points of the scan grid: (P, 2) [m] and their ring-area weights [m^2].

    Rings at the centres of ``rings`` equal annuli between the disc's rim and the outer
    rim, ``per_ring`` points each (turned by half a step on every other ring); the disc's
    points on a circle of half its radius.
    """
    width = (outer_radius - inner_radius) / options.rings
    points, weights = [], []
    for ring in range(options.rings):
        radius = inner_radius + (ring + 0.5) * width
        angles = 2 * np.pi * (np.arange(options.per_ring) + 0.5 * (ring % 2)) / options.per_ring
        points.append(np.column_stack([radius * np.cos(angles), radius * np.sin(angles)]))
        weights.append(np.full(options.per_ring, 2 * np.pi * radius * width / options.per_ring))
    if options.disc_points and inner_radius > 0:
        angles = 2 * np.pi * (np.arange(options.disc_points) + 0.5) / options.disc_points
        points.append(0.5 * inner_radius * np.column_stack([np.cos(angles), np.sin(angles)]))
        weights.append(np.full(options.disc_points,
                               np.pi * inner_radius ** 2 / options.disc_points))
    return np.vstack(points), np.concatenate(weights)


def modal_damping(study: Study, damping_ratio: float = 0.0):
    """``mode -> (b/m)`` [1/s] of the export: the study's own modal damping by label
    (:func:`copdea_fem.forced_response.run.modal_damping`, eq. 19: what the model's quality
    factors hold), plus ``2 damping_ratio omega`` at the mode's FE frequency (a damping the
    model lacks)."""
    from copdea_fem.forced_response.run import modal_damping as by_label

    def damping(mode) -> float:
        return (float(by_label([mode.label], [mode.kind], study)[0])
                + 4 * math.pi * damping_ratio * mode.freq_hz)

    return damping


def synthesise_scan(study: Study, options: ScanOptions, rng, name: str = "scan"):
    """One condition's export from the FE forced response of ``study`` (the truth: effects
    already on; module notes).

    Returns
    -------
    (ScanData, dict)
        The export (path ``<name>.uff``, not written) and the truth: the electrode's
        imperfection and, per FE label, the frequency [Hz] and damping ratio as driven and
        the mode's quasi-static displacement per volt at the points [m/V].
    """
    from copdea_fem.diagnosis.fe import BAND_MARGIN, fe_study
    from copdea_fem.fe import ElectrodeImperfection, engine_for, run_solve
    from copdea_fem.forced_response.scan import scan_response
    from copdea_fem.measured import ScanData
    from copdea_fem.vibrometer.pairing import unit_key

    frequencies = options.frequencies()
    solved_study = fe_study(study, f_max=float(frequencies[-1]) * BAND_MARGIN)
    result = run_solve(solved_study, engine=engine_for(solved_study, forced_response=True))
    state = result.state
    orders = sorted({int(mode.m) for mode in result.modes if mode.kind != "air" and mode.m})
    imperfection = ElectrodeImperfection.random(orders, options.imperfection, rng)
    scatter = {}

    def factor(label):
        # one draw per mode, as before; the members of a pair (m,n)a/b share their pair's
        # (the scatter is the model's error, common to both: a split is the device's;
        # unit_key also joins a member whose letter ties with its partner's)
        draw = math.exp(rng.normal(0, options.frequency_noise))
        return scatter.setdefault(unit_key(label) or label, draw)

    reference, _ = psv_reference_grid(state.outer_radius, state.inner_radius, options)
    positions = result.engine.prestressed_positions(state, reference, study.load.z)
    response = scan_response(result, solved_study, positions, frequencies, imperfection,
                             damping_per_mass=modal_damping(study, options.damping_ratio),
                             frequency_factors=factor)
    n_points = len(positions)
    channel_point = np.repeat(np.arange(n_points), 3)
    channel_direction = np.tile(np.eye(3), (n_points, 1))
    values = response.velocity.reshape(3 * n_points, frequencies.size)
    level = float(np.max(np.abs(values))) * 10 ** (-options.snr_db / 20)
    values = values + level / math.sqrt(2) * (rng.standard_normal(values.shape)
                                               + 1j * rng.standard_normal(values.shape))
    scan = ScanData(path=Path(f"{name}.uff"), nodes=np.arange(1, n_points + 1),
                    positions=positions, channel_point=channel_point,
                    channel_direction=channel_direction, frequencies=frequencies,
                    values=values)
    logger.info("synth %s: FE forced response of %d modes at %d points x 3 directions, %d "
                "lines", name, len(response.modes), n_points, frequencies.size)
    truth = {"imperfection": {"orders": list(imperfection.orders),
                              "amplitudes": list(imperfection.amplitudes),
                              "angles_rad": list(imperfection.angles)},
             "modes": response.modes}
    return scan, truth


@dataclass
class ScannedCondition:
    """One condition of a synthetic scan set: its name, its study overrides, the export
    (:class:`~copdea_fem.vibrometer.scan.ScanData`, not yet written) and its truth
    (:func:`synthesise_scan`)."""

    name: str
    overrides: dict
    scan: object
    truth: dict


def synthesise_scan_set(study: Study, effects: dict, conditions: list[tuple[str, dict]],
                        options: ScanOptions) -> list[ScannedCondition]:
    """Solve and export every condition of a set of scans (:func:`synthesise_scan` with the
    effects switched on in the truth); nothing written (:func:`write_scan_set`).

    Parameters
    ----------
    study : Study
        The base study (the model that will be diagnosed).
    effects : dict
        ``{effect id: parameter values}`` switched on in the truth.
    conditions : list of (name, overrides)
    options : ScanOptions
    """
    from copdea_fem.diagnosis.effects import CATALOGUE
    from copdea_fem.diagnosis.ring_predictor import state_overrides

    options.check()
    rng = np.random.default_rng(options.seed)
    state = []
    for effect_id, values in effects.items():
        entry = CATALOGUE[effect_id]
        for required in entry.requires:
            if required not in effects and not CATALOGUE[required].is_on(study):
                state.append((required, CATALOGUE[required].defaults))
        state.append((effect_id, tuple(values) if values is not None else entry.defaults))
    scanned = []
    for name, overrides in conditions:
        condition_study = study.replace(overrides)
        truth_study = (condition_study.replace(state_overrides(condition_study, state))
                       if state else condition_study)
        scan, truth = synthesise_scan(truth_study, options, rng, name)
        scanned.append(ScannedCondition(name, dict(overrides), scan, truth))
    return scanned


def write_scan_set(study: Study, effects: dict, scanned: list[ScannedCondition],
                   options: ScanOptions, out_dir, *, observed=None) -> list[Path]:
    """Write a measured set of scans (:func:`synthesise_scan_set`) into ``out_dir``:
    measured.yaml (``model: fe``, one ``scan:`` per condition), base_study.yaml,
    ``<condition>.uff`` and synth_truth.json.

    Parameters
    ----------
    study : Study
        The base study (the model that will be diagnosed).
    effects : dict
        ``{effect id: parameter values}`` switched on in the truth.
    scanned : list of ScannedCondition
    options : ScanOptions
    out_dir : path
        An existing (staging) folder.
    observed : list of str, optional
        ``observed:`` of the written measured.yaml.
    """
    from copdea_fem.measured import write_scan

    out = Path(out_dir)
    files = [out / "measured.yaml", out / "base_study.yaml"]
    dump_resolved(study, out / "base_study.yaml")
    entries, truths = [], {}
    for item in scanned:
        path = write_scan(out / f"{item.name}.uff", item.scan, binary=True)
        files.append(path)
        low = max(options.f_min, 2 * options.resolution)
        entries.append({"name": item.name, "set": dict(item.overrides), "scan": path.name,
                        "band": [f"{low:g} Hz", f"{float(item.scan.frequencies[-1]):g} Hz"]})
        truths[item.name] = item.truth
    manifest = {
        "name": f"synth_scan_{'_'.join(effects) or 'nothing'}_seed{options.seed}",
        "description": "synthetic vibrometer export (copdea-fem synth --format uff): FE "
                       "forced response on the scan grid, effects "
                       + (", ".join(effects) or "none") + f" on, seed {options.seed}",
        "base_study": "base_study.yaml",
        "model": "fe",
        # the export's damping is the base study's modal b/m; its Q's are not weighed
        # (module notes)
        "noise": {"frequency_relative": max(options.frequency_noise, 0.005),
                  "quality_relative": QUALITY_UNINFORMATIVE,
                  "missing_probability": 0.1, "spurious_per_condition": 0.3},
        **({"observed": list(observed)} if observed else {}),
        "conditions": entries}
    (out / "measured.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    (out / "synth_truth.json").write_text(json.dumps(
        {"effects": {k: list(v) for k, v in effects.items()}, "options": asdict(options),
         "conditions": truths}, indent=1, default=float))
    files.append(out / "synth_truth.json")
    return files


__all__ = ["QUALITY_UNINFORMATIVE", "ScanOptions", "ScannedCondition", "modal_damping",
           "psv_reference_grid", "synthesise_scan", "synthesise_scan_set", "write_scan_set"]
