r"""Synthetic vibrometer exports made by the FE (``copdea-fem synth --format uff``).

The *truth* is the FE of the study with the chosen effects switched on (as the diagnosis
switches them, :func:`copdea_fem.diagnosis.engine.state_overrides`; solved as the diagnosis
solves its model of record, :func:`copdea_fem.diagnosis.fe.fe_study`); the written
``measured.yaml`` names the study *without* them as its base, so diagnosing it should find
them.  What the export holds, per condition, is what a PSV-type scanning vibrometer exports:

- the scan grid of the paper (Fig. 5d): points on rings of the membrane and a few on the
  disc (default 5 rings x 16 = 80 on the membrane, 4 on the disc), at their places on the
  *prestressed* device (:func:`copdea_fem.vibrometer.sampling.prestressed_positions`),
  three velocity components each;
- FRFs of velocity per volt of drive, the modal sum of the FE's structural modes
  (standard ``e^{+i omega t}`` convention, mobility)

  .. math::  H_c(\omega) = \sum_k A p_k \, \omega_k^2 \,
             \frac{i \omega \, \phi_{ck}}{\omega_k^2 - \omega^2 + 2 i \zeta_k \omega_k \omega}

  with ``phi_ck`` the mode's displacement along channel c (peak |u| = 1:
  :class:`copdea_fem.vibrometer.sampling.ScanSampler`), ``A`` = 1 um/V the quasi-static
  displacement scale of a fully driven mode, ``zeta_k`` the FE's (radiation) damping ratio
  plus ``damping_ratio`` (material loss; the FE in vacuo has none), and the participation
  ``p_k``: a uniform electrostatic pressure drives a mode by its mean normal displacement
  over the device (``|sum_i w_i u_z,i| / sum_i w_i``, ring-area weights ``w_i``: zero for
  m >= 1 on a perfect device), to which *imperfections* add a random
  ``imperfection x RMS(u_z) x LogNormal(0, 1/2)`` for every mode, so that the
  non-axisymmetric modes light up as they do in the paper's scans (Fig. 7);
- frequency scatter: each mode moved by ``exp(N(0, frequency_noise))``;
- measurement noise: complex Gaussian, ``snr_db`` below the largest |H| of the export.

The written ``measured.yaml`` declares the quality factors uninformative
(``noise.quality_relative`` = :data:`QUALITY_UNINFORMATIVE`): they hold the material damping
``damping_ratio`` that the truth was given and the base model lacks, which the diagnosis
would otherwise (rightly) report as a missing damping effect beside the hidden ones - on
five seeds with informative Q's it named ``viscoelastic_membrane`` after ``air_loading``
twice.

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

from copdea_fem.study import Study, StudyError, dump_resolved

logger = logging.getLogger(__name__)

#: Quasi-static displacement per volt of a mode with participation 1 [m/V].
DISPLACEMENT_SCALE = 1e-6
#: ``noise.quality_relative`` of a synthetic set: the bound of
#: :data:`copdea_fem.diagnosis.measured.NOISE_BOUNDS`, a 1-sigma scatter of ln Q of 5 (a
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
        Material damping ratio added to every mode [-].
    imperfection : float
        Participation of imperfections relative to the RMS normal displacement [-].
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
    damping_ratio: float = 0.01
    imperfection: float = 0.5
    seed: int = 0

    def check(self) -> None:
        """Refuse settings outside their bounds (StudyError naming the option)."""
        integers = {"rings": (1, 50), "per_ring": (3, 360), "disc_points": (0, 100)}
        numbers = {"f_min": (0.0, 1e5), "f_max": (1.0, 1e5), "resolution": (1e-3, 1e3),
                   "frequency_noise": (0.0, 0.2), "snr_db": (0.0, 200.0),
                   "damping_ratio": (1e-4, 0.5), "imperfection": (0.0, 10.0)}
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


def synthesise_scan(study: Study, options: ScanOptions, rng, name: str = "scan"):
    """One condition's export from the FE of ``study`` (the truth: effects already on).

    Returns
    -------
    (ScanData, dict)
        The export (path ``<name>.uff``, not written) and the truth (FE labels, their
        frequencies [Hz] as exported, participations).
    """
    from copdea_fem.diagnosis.fe import fe_study
    from copdea_fem.fe.pipeline import run_solve
    from copdea_fem.vibrometer.model_shapes import STRUCTURAL_KINDS
    from copdea_fem.vibrometer.sampling import ScanSampler, prestressed_positions
    from copdea_fem.vibrometer.scan import ScanData

    frequencies = options.frequencies()
    result = run_solve(fe_study(study, f_max=float(frequencies[-1]) * 1.1))
    state = result.state
    modes = [m for m in result.modes if m.kind in STRUCTURAL_KINDS and m.label]
    reference, weights = psv_reference_grid(state.outer_radius, state.inner_radius, options)
    positions = prestressed_positions(state, reference, study["load"]["z"])
    sampler = ScanSampler(state, positions)
    n_points = len(positions)
    channel_point = np.repeat(np.arange(n_points), 3)
    channel_direction = np.tile(np.eye(3), (n_points, 1))
    omega = 2 * np.pi * frequencies
    values = np.zeros((3 * n_points, frequencies.size), dtype=complex)
    truth = {}
    for mode in modes:
        shape = sampler.displacement(mode)                         # (P, 3), peak |u| = 1
        normal = shape[:, 2]
        uniform = abs(np.sum(weights * normal)) / np.sum(weights)
        rms = float(np.sqrt(np.mean(np.abs(normal) ** 2)))
        participation = uniform + options.imperfection * rms * float(
            np.exp(rng.normal(0, 0.5)))
        frequency = mode.freq_hz * math.exp(rng.normal(0, options.frequency_noise))
        zeta = mode.damping_ratio + options.damping_ratio
        omega_k = 2 * np.pi * frequency
        # a real, phase-aligned shape (the FE's complex one, turned to its largest component)
        flat = shape.ravel()
        peak = flat[np.argmax(np.abs(flat))]
        real_shape = np.real(flat * np.conj(peak) / abs(peak)) if abs(peak) > 0 else flat.real
        response = (DISPLACEMENT_SCALE * participation * omega_k ** 2 * 1j * omega
                    / (omega_k ** 2 - omega ** 2 + 2j * zeta * omega_k * omega))
        values += real_shape[:, None] * response[None, :]
        truth[mode.label] = {"freq_hz": frequency, "participation": participation,
                             "damping_ratio": zeta}
    level = float(np.max(np.abs(values))) * 10 ** (-options.snr_db / 20)
    values = values + level / math.sqrt(2) * (rng.standard_normal(values.shape)
                                               + 1j * rng.standard_normal(values.shape))
    scan = ScanData(path=Path(f"{name}.uff"), nodes=np.arange(1, n_points + 1),
                    positions=positions, channel_point=channel_point,
                    channel_direction=channel_direction, frequencies=frequencies,
                    values=values)
    logger.info("synth %s: %d FE modes summed at %d points x 3 directions, %d lines", name,
                len(modes), n_points, frequencies.size)
    return scan, truth


def write_scan_set(study: Study, effects: dict, conditions: list[tuple[str, dict]],
                   options: ScanOptions, out_dir, *, observed=None) -> list[Path]:
    """Solve, export and write a measured set of scans into ``out_dir``: measured.yaml
    (``model: fe``, one ``scan:`` per condition), base_study.yaml, ``<condition>.uff`` and
    synth_truth.json.

    Parameters
    ----------
    study : Study
        The base study (the model that will be diagnosed).
    effects : dict
        ``{effect id: parameter values}`` switched on in the truth.
    conditions : list of (name, overrides)
    options : ScanOptions
    out_dir : path
        An existing (staging) folder.
    observed : list of str, optional
        ``observed:`` of the written measured.yaml.
    """
    from copdea_fem.diagnosis.effects import CATALOGUE
    from copdea_fem.diagnosis.engine import state_overrides
    from copdea_fem.vibrometer.uff import write_scan

    options.check()
    rng = np.random.default_rng(options.seed)
    out = Path(out_dir)
    state = []
    for effect_id, values in effects.items():
        entry = CATALOGUE[effect_id]
        for required in entry.requires:
            if required not in effects and not CATALOGUE[required].is_on(study):
                state.append((required, CATALOGUE[required].defaults))
        state.append((effect_id, tuple(values) if values is not None else entry.defaults))
    files = [out / "measured.yaml", out / "base_study.yaml"]
    dump_resolved(study, out / "base_study.yaml")
    entries, truths = [], {}
    for name, overrides in conditions:
        condition_study = study.replace(overrides)
        truth_study = (condition_study.replace(state_overrides(condition_study, state))
                       if state else condition_study)
        scan, truth = synthesise_scan(truth_study, options, rng, name)
        path = write_scan(out / f"{name}.uff", scan, binary=True)
        files.append(path)
        low = max(options.f_min, 2 * options.resolution)
        entries.append({"name": name, "set": dict(overrides), "scan": path.name,
                        "band": [f"{low:g} Hz", f"{float(scan.frequencies[-1]):g} Hz"]})
        truths[name] = truth
    manifest = {
        "name": f"synth_scan_{'_'.join(effects) or 'nothing'}_seed{options.seed}",
        "description": "synthetic vibrometer export (copdea-fem synth --format uff): FE "
                       "modal sum on the scan grid, effects "
                       + (", ".join(effects) or "none") + f" on, seed {options.seed}",
        "base_study": "base_study.yaml",
        "model": "fe",
        # the export's quality factors hold the material damping the truth was given and no
        # FE in vacuo has: declared uninformative (sigma_Q at its bound), so that what the
        # diagnosis is asked to find is the effects switched on, not that damping
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


__all__ = ["DISPLACEMENT_SCALE", "QUALITY_UNINFORMATIVE", "ScanOptions", "psv_reference_grid", "synthesise_scan",
           "write_scan_set"]
