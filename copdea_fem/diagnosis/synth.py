"""Synthetic measurements from the model with chosen effects on (``copdea-fem synth``).

The *truth* is the study with the chosen effects switched on (default or
given parameters); the written ``measured.yaml`` names the study *without*
them as its base, so diagnosing it should find them.  Realistic scatter,
all drawn from one seeded generator (:func:`numpy.random.default_rng`):

- frequency noise: each mode of each condition is moved by a factor
  ``exp(eps)``, ``eps ~ N(0, frequency_noise)`` (1-2 %: the identification
  scatter of Sect. 4.3 plus what no model holds), applied to the mode's
  stiffness so that the spectra peak where the resonance list says; the
  spring's wave speed gets its own factor (moves P2, P3);
- quality factors: the model's Q times ``exp(N(0, quality_noise))``;
- missing peaks: each mode in the band is dropped from the resonance list
  with probability ``missing_probability`` (and its modal force cut to 0.5 %
  in the spectrum, so it drowns in the floor);
- ``spurious`` peaks: unlabelled peaks at log-uniform random frequencies in
  random conditions (a set-up resonance, an unlabelled non-axisymmetric
  mode), also added to the spectrum as a narrow bump;
- labels: each peak keeps its label with probability ``label_fraction``;
  its kind (pumping / axisymmetric: visible in the vibrometer's shapes) is
  always written;
- spectra (average over the scan grid, ``v_axial, v_radial``): the model's
  spectra under the study's chirp times ``exp(N(0, amplitude_noise))`` per
  line and component, plus a floor of 0.2 % of the largest value; only
  where the chirp drives anything (z > 0 and V_b > 0).

The data are the reduced (ring) model's, so the ``measured.yaml`` names it as the
model of record (``model: reduced``): diagnosing it tests that the diagnosis can
invert its own surrogate, not the FE (for that: ``tests/diagnosis/fe_battery.py``).

Written: ``measured.yaml``, ``base_study.yaml`` (the study as given,
resolved), ``<condition>_resonances.csv``, ``<condition>_spectrum.csv`` and
``synth_truth.json`` (effects, parameters, seed, options, true frequencies).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import yaml

from copdea_fem.diagnosis.effects import CATALOGUE, effect
from copdea_fem.diagnosis.ring_predictor import RingPredictor
from copdea_fem.inputs import parse_yaml
from copdea_fem.measured import Condition, MeasuredSet, NoiseModel
from copdea_fem.study import Study, StudyError, dump_resolved

DEFAULT_CONDITIONS = ({"load.z": "11 mm", "load.voltage": "2 kV"},
                      {"load.z": "16 mm", "load.voltage": "2 kV"},
                      {"load.z": "18 mm", "load.voltage": "2 kV"},
                      {"load.z": "16 mm", "load.voltage": "1 kV"},
                      {"load.z": "16 mm", "load.voltage": "3 kV"})


#: Largest seed of the generators (:func:`numpy.random.default_rng` takes any integer >= 0;
#: 2^63 - 1 keeps it a machine integer in the truth files).
MAX_SEED = 2**63 - 1


@dataclass(frozen=True)
class SynthOptions:
    """Scatter of the synthetic measurement (module notes); all dimensionless."""

    frequency_noise: float = 0.015
    quality_noise: float = 0.15
    amplitude_noise: float = 0.10
    missing_probability: float = 0.10
    spurious: int = 1
    label_fraction: float = 0.5
    spectra: bool = True
    seed: int = 0

    def check(self) -> None:
        limits = {"frequency_noise": (0, 0.2), "quality_noise": (0, 2),
                  "amplitude_noise": (0, 2), "missing_probability": (0, 0.9),
                  "label_fraction": (0, 1)}
        for name, (lo, hi) in limits.items():
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise StudyError(f"--{name.replace('_', '-')} = {value!r} is not allowed; "
                                 f"allowed: [{lo:g}, {hi:g}]")
        if not 0 <= self.spurious <= 100:
            raise StudyError(f"--spurious = {self.spurious!r} is not allowed; allowed: 0 to 100")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not (
                0 <= self.seed <= MAX_SEED):
            raise StudyError(f"--seed = {self.seed!r} is not allowed; allowed: an integer in "
                             f"[0, {MAX_SEED}]")


@dataclass
class SynthCondition:
    name: str
    overrides: dict
    resonances: list = field(default_factory=list)
    spectrum: dict | None = None
    truth: dict = field(default_factory=dict)


def parse_conditions(text: str | None) -> list[dict]:
    """``"load.z=11 mm, load.voltage=2 kV; load.z=16 mm"`` -> list of override dicts."""
    if text is None or not str(text).strip():
        return [dict(c) for c in DEFAULT_CONDITIONS]
    conditions = []
    for chunk in str(text).split(";"):
        if not chunk.strip():
            continue
        overrides = {}
        for item in chunk.split(","):
            if not item.strip():
                continue
            if "=" not in item:
                raise StudyError(f"--conditions item {item.strip()!r} is not allowed; allowed: "
                                 "SECTION.KEY=VALUE pairs separated by ',' within a condition "
                                 "and ';' between conditions, e.g. 'load.z=11 mm, load.voltage="
                                 "2 kV; load.z=16 mm'")
            key, value = item.split("=", 1)
            parsed = parse_yaml(value, f"--conditions {key.strip()}", StudyError)
            overrides[key.strip()] = value.strip() if parsed is None else parsed
        conditions.append(overrides)
    if not conditions:
        raise StudyError(f"--conditions = {text!r} is not allowed; allowed: at least one "
                         "condition")
    return conditions


def parse_parameters(items) -> dict:
    """``["air_loading.scale=1.2", "spring_mass.mass=2 g"]`` -> {effect: {name: SI value}}."""
    from copdea_fem.study import Key, convert_value
    out: dict = {}
    for item in items or []:
        if "=" not in item or "." not in item.split("=", 1)[0]:
            raise StudyError(f"--param {item!r} is not allowed; allowed: EFFECT.PARAMETER=VALUE, "
                             "e.g. air_loading.scale=1.2")
        name, value = item.split("=", 1)
        effect_id, parameter = name.strip().split(".", 1)
        entry = effect(effect_id)
        spec = next((p for p in entry.parameters if p.name == parameter), None)
        if spec is None:
            raise StudyError(f"--param {name.strip()} = {value!r} is not allowed (unknown "
                             f"parameter); allowed: {entry.parameter_names or 'none'} of "
                             f"{effect_id}")
        key = Key(spec.unit, spec.default, spec.description, minimum=spec.lower,
                  maximum=spec.upper)
        parsed = parse_yaml(value, f"--param {name.strip()}", StudyError)
        out.setdefault(effect_id, {})[parameter] = convert_value(
            f"--param {name.strip()}", key, value.strip() if isinstance(parsed, str) or
            parsed is None else parsed)
    return out


def condition_name(study: Study, overrides: dict, index: int, taken: set) -> str:
    """A condition's name from its operating point (``z16_v2``), unique among ``taken``."""
    parts = []
    for key in overrides:
        if key == "load.z":
            parts.append(f"z{study.load.z * 1e3:g}")
        elif key == "load.voltage":
            parts.append(f"v{study.load.voltage / 1e3:g}")
        elif key == "geometry.inner_radius":
            parts.append(f"ri{study.geometry.inner_radius * 1e3:g}")
    name = "_".join(parts) or f"c{index + 1}"
    name = name.replace("-", "m")
    candidate, suffix = name, 2
    while candidate in taken:
        candidate, suffix = f"{name}_{suffix}", suffix + 1
    taken.add(candidate)
    return candidate


def synthesise(study: Study, effects: dict, conditions: list[dict],
               options: SynthOptions = SynthOptions()) -> list[SynthCondition]:
    """Synthetic data of every condition (module notes).

    Parameters
    ----------
    study : Study
        The base study (the model that will be diagnosed).
    effects : dict
        ``{effect id: parameter values tuple or None (defaults)}`` switched on in the truth.
    conditions : list of dict
        Overrides of each condition.
    """
    options.check()
    rng = np.random.default_rng(options.seed)
    state = []
    for effect_id, values in effects.items():
        entry = effect(effect_id)
        if entry.engine != "reduced":
            raise StudyError(f"--effects {effect_id} is not allowed: it needs the coupled FE "
                             "engine, which this version does not have; allowed: "
                             + ", ".join(e.id for e in CATALOGUE.values() if e.engine == "reduced"))
        for required in entry.requires:
            if required not in effects and not CATALOGUE[required].is_on(study):
                state.append((required, CATALOGUE[required].defaults))
        state.append((effect_id, tuple(values) if values is not None else entry.defaults))
    prepared, taken = [], set()
    for index, overrides in enumerate(conditions):
        try:
            condition_study = study.replace(overrides)
        except StudyError as error:
            raise StudyError(f"--conditions #{index + 1}: {error}") from None
        x = condition_study.excitation
        band = (max(x.f_start, 1.0 / x.duration), x.f_end)
        name = condition_name(condition_study, overrides, index, taken)
        prepared.append(Condition(name=name, overrides=dict(overrides), resonances=None,
                                  spectrum=None, band=band))
    measured = MeasuredSet(name="synth", description="", path=None, base_study=study,
                           conditions=tuple(prepared), noise=NoiseModel())
    engine = RingPredictor(measured)
    out = []
    for condition in prepared:
        truth_study = engine.study(condition, tuple(state))
        exact = engine.predict_study(truth_study, condition)
        labels = [m.label for m in exact.modes if m.label in exact.reference.labels]
        perturbation = {label: math.exp(rng.normal(0, options.frequency_noise))
                        for label in labels}
        perturbation["spring"] = math.exp(rng.normal(0, options.frequency_noise))
        missing = {}
        for mode in exact.modes:
            missing[mode.label] = bool(rng.random() < options.missing_probability)
        for label, gone in missing.items():
            if gone and label in exact.reference.labels:
                perturbation[f"force:{label}"] = 0.005
        noisy = engine.predict_study(truth_study, condition, perturbation)
        item = SynthCondition(name=condition.name, overrides=condition.overrides)
        lo, hi = condition.band
        for mode in noisy.modes:
            if not (mode.expected and lo <= mode.frequency_hz <= hi) or missing[mode.label]:
                continue
            label = mode.label if rng.random() < options.label_fraction else ""
            quality = (mode.quality_factor * math.exp(rng.normal(0, options.quality_noise))
                       if math.isfinite(mode.quality_factor) else math.nan)
            item.resonances.append({"freq_hz": mode.frequency_hz, "label": label,
                                    "quality_factor": quality, "kind": mode.kind})
        item.truth = {"state": [[effect_id, list(values)] for effect_id, values in state],
                      "modes": {m.label: m.frequency_hz for m in exact.modes},
                      "perturbed": {m.label: m.frequency_hz for m in noisy.modes},
                      "missing": [label for label, gone in missing.items() if gone]}
        drive = truth_study.load.z > 0 and truth_study.load.voltage > 0
        if options.spectra and drive:
            result = noisy.spectra()
            item.spectrum = {"freq_hz": result.frequency_hz,
                             "v_axial": result.average_axial.copy(),
                             "v_radial": result.average_radial.copy()}
        out.append(item)
    for _ in range(options.spurious):
        item = out[int(rng.integers(len(out)))]
        lo, hi = prepared[0].band
        frequency = float(math.exp(rng.uniform(math.log(max(lo, 20.0)), math.log(hi))))
        quality = float(rng.uniform(30, 100))
        item.resonances.append({"freq_hz": frequency, "label": "", "quality_factor": quality,
                                "kind": ""})
        item.truth.setdefault("spurious", []).append(frequency)
        if item.spectrum is not None:
            f = item.spectrum["freq_hz"]
            bump = 1.0 / np.sqrt(1 + (2 * quality * (f - frequency) / frequency) ** 2)
            height = 0.2 * float(np.max(item.spectrum["v_axial"]))
            item.spectrum["v_axial"] = item.spectrum["v_axial"] + height * bump
            item.spectrum["v_radial"] = item.spectrum["v_radial"] + 0.5 * height * bump
    for item in out:
        item.resonances.sort(key=lambda r: r["freq_hz"])
        if item.spectrum is not None:
            for key in ("v_axial", "v_radial"):
                values = item.spectrum[key]
                floor = 2e-3 * float(np.max(values))
                noise = np.exp(rng.normal(0, options.amplitude_noise, values.size))
                item.spectrum[key] = values * noise + floor * np.abs(rng.normal(0, 1, values.size))
    return out


def write_synthetic(study: Study, effects: dict, items: list[SynthCondition],
                    options: SynthOptions, out_dir) -> list[Path]:
    """Write measured.yaml, base_study.yaml, the CSVs and synth_truth.json into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    dump_resolved(study, out / "base_study.yaml")
    files.append(out / "base_study.yaml")
    conditions = []
    for item in items:
        entry = {"name": item.name, "set": item.overrides}
        if item.resonances:
            path = out / f"{item.name}_resonances.csv"
            with path.open("w", newline="") as handle:
                writer = csv.writer(handle, lineterminator="\n")
                writer.writerow(["freq_hz", "label", "quality_factor", "kind"])
                for r in item.resonances:
                    quality = "" if not math.isfinite(r["quality_factor"]) else \
                        f"{r['quality_factor']:.4g}"
                    writer.writerow([f"{r['freq_hz']:.6g}", r["label"], quality, r["kind"]])
            entry["resonances"] = path.name
            files.append(path)
        if item.spectrum is not None:
            path = out / f"{item.name}_spectrum.csv"
            s = item.spectrum
            lines = ["freq_hz,v_axial,v_radial"] + [
                f"{f:.6g},{a:.5g},{r:.5g}" for f, a, r in zip(s["freq_hz"], s["v_axial"],
                                                              s["v_radial"])]
            path.write_text("\n".join(lines) + "\n")
            entry["spectrum"] = path.name
            files.append(path)
        if "resonances" not in entry and "spectrum" not in entry:
            continue                   # every peak of this condition went missing
        conditions.append(entry)
    n = max(len(conditions), 1)
    manifest = {
        "name": f"synth_{'_'.join(effects) or 'nothing'}_seed{options.seed}",
        "description": "synthetic measurement (copdea-fem synth): effects "
                       + (", ".join(effects) or "none") + f" on, seed {options.seed}",
        "base_study": "base_study.yaml",
        "model": "reduced",       # made by the ring model: diagnosed against it
        "noise": {"frequency_relative": max(options.frequency_noise, 1e-4),
                  "quality_relative": max(options.quality_noise, 1e-3),
                  "missing_probability": min(max(options.missing_probability, 1e-3), 0.9),
                  "spurious_per_condition": min(max(options.spurious / n, 1e-3), 20.0)},
        "conditions": conditions}
    (out / "measured.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    files.insert(0, out / "measured.yaml")
    truth = {"effects": {k: list(v) if v is not None else list(effect(k).defaults)
                         for k, v in effects.items()},
             "options": asdict(options),
             "conditions": {item.name: item.truth for item in items}}
    (out / "synth_truth.json").write_text(json.dumps(truth, indent=1, default=float))
    files.append(out / "synth_truth.json")
    return files
