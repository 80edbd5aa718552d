"""Blind battery of the diagnosis on data the FE made (issue 13).

The "measured" resonances are FE frequencies (coupled with air, or in vacuo) of
the paper's G1 sample with this file's own noise -- not ``synth``'s reduced
engine and not its noise code: 1 % log-normal frequency scatter, each mode
missed with probability 10 %, Poisson(0.3) spurious peaks per condition,
every peak labelled with probability 1/2 (labels from the FE), kinds unknown
for unlabelled peaks.  A vibrometer on a nominally axisymmetric device sees
the axisymmetric modes and, through imperfections, the low non-axisymmetric
ones: orders m <= :data:`SEEN_ORDERS` are kept.

FE solves are cached in ``tests/data/fe_cache`` (keyed by the FE study's hash and
the FE code's fingerprint, :func:`copdea_fem.diagnosis.fe.fe_key`): the tests read it
and the diagnosis reads it too (the FE model of record of the same studies).  A change
to the FE code (:data:`copdea_fem.fingerprint.FE_SOURCES`) leaves no entry with the new
keys: the tests that read the cache then fail at once naming the refill command
(``tests/diagnosis/conftest.py``), rather than solving for many minutes.  Refill:
``python tests/diagnosis/fe_battery.py --refill`` (empties the folder, fills the battery's
studies, then runs the diagnosis tests with ``COPDEA_FEM_FE_REFILL=1`` so that they
write every other FE study they ask for).
"""

from __future__ import annotations

import copy
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from copdea_fem.diagnosis.fe import BAND_MARGIN, FEModel, fe_key, fe_study
from copdea_fem.study import parse_study

FE_CACHE = Path(__file__).resolve().parent.parent / "data" / "fe_cache"
BAND = (20.0, 1000.0)            # Hz
SCATTER = 0.01                   # 1-sigma of ln f
P_MISS = 0.1
SPURIOUS = 0.3                   # per condition
SEEN_ORDERS = 2

DRY = {"name": "g1_fe", "description": "G1 (Table 1), disc held, in vacuo",
       "disc": {"mass": "3.0 g", "motion": "held"}, "output": {"plots": False}}
AIR5 = [{"load.z": f"{z} mm", "load.voltage": "2 kV"} for z in (11, 16, 18)] + \
    [{"load.z": "16 mm", "load.voltage": f"{v} kV"} for v in (1, 3)]
VOLT6 = [{"load.z": f"{z} mm", "load.voltage": f"{v} kV"} for z in (11, 16) for v in (1, 2, 3)]


def _with(base: dict, **sections) -> dict:
    out = copy.deepcopy(base)
    for section, values in sections.items():
        out.setdefault(section, {}).update(values)
    return out


AIR_SQUARE = _with(DRY, air={"enabled": True})                 # default frame: square 80 mm
AIR_FRAMELESS = _with(DRY, air={"enabled": True}, geometry={"frame": "none"})


@dataclass(frozen=True)
class Case:
    """Base model, the FE study that makes the data, conditions, the right verdict; with
    ``quality``, each peak also carries the FE's quality factor Q = 1/(2 zeta) with
    log-normal scatter :data:`Q_SCATTER`; ``candidates``: measured.yaml's (None: all)."""

    base: dict
    truth: dict
    conditions: list
    missing: tuple
    quality: bool = False
    candidates: tuple | None = None


CASES = {
    "air_hidden": Case(DRY, AIR_SQUARE, AIR5, ("air_loading",)),
    "nothing_hidden": Case(DRY, DRY, AIR5, ()),
    "electrostatic_hidden": Case(_with(DRY, effects={"maxwell_scale": 0.0}), DRY, VOLT6,
                                 ("electrostatic_softening",)),
    "frame_hidden": Case(AIR_FRAMELESS, AIR_SQUARE, AIR5, ("frame_reflection",)),
    "air_base": Case(AIR_SQUARE, AIR_SQUARE, AIR5, ()),
}


# Issue 23: material damping, evaluated by the FE's damped eigen step.  A strongly
# viscoelastic film (acrylic VHB-like: the glassy modulus 3x the relaxed one, tau = 0.3 ms,
# its loss peak at 530 Hz, mid-band): G1 in vacuo at 2 kV, z = 16 mm gets Q = 43 on (0,1)
# and +1.2 % in frequency.  Its null: a film damped by something else the base states
# (mass-proportional Rayleigh damping, alpha = 64 1/s: Q = 50 on (0,1) at z = 16 mm) and
# no modal b/m, with data made by that same FE.
Q_SCATTER = 0.10                 # 1-sigma of ln Q (a half-power width read to 10 %)
VISCO_TERM = {"modulus_ratio": 2.0, "relaxation_time": "0.3 ms"}
DRY_VISCO = _with(DRY, membrane={"prony": [VISCO_TERM]})
NO_MODAL_DAMPING = {"damping_p1": 0.0, "damping_01": 0.0, "damping_02": 0.0,
                    "damping_higher": 0.0}
DRY_RAYLEIGH = _with(DRY, membrane={"rayleigh_alpha": "64 1/s"}, reduced=NO_MODAL_DAMPING)
# no air candidates in the null: their coupled FE solves with damping would cost minutes
MATERIAL_CANDIDATES = ("viscoelastic_membrane", "viscoelastic_stiffening", "modal_damping",
                       "uniform_stiffness", "electrostatic_softening")

DAMPING_CASES = {
    "viscoelastic_hidden": Case(DRY, DRY_VISCO, AIR5, ("viscoelastic_membrane",),
                                quality=True),
    "damping_known": Case(DRY_RAYLEIGH, DRY_RAYLEIGH, AIR5, (), quality=True,
                          candidates=MATERIAL_CANDIDATES),
}
ALL_CASES = {**CASES, **DAMPING_CASES}


def condition_name(overrides: dict) -> str:
    z = re.sub(r"\s*mm", "", overrides["load.z"])
    v = re.sub(r"\s*kV", "", overrides["load.voltage"])
    return f"z{z}_v{v}"


def truth_modes(case: Case, fe: FEModel | None = None) -> dict:
    """FE modes of the truth at every condition: {condition name: FEResult}."""
    fe = fe or FEModel(cache_dir=FE_CACHE)
    truth = parse_study(case.truth, name="truth")
    return {condition_name(o): fe.modes(truth.replace(o), f_max=BAND_MARGIN * BAND[1])
            for o in case.conditions}


def written_label(label: str) -> str:
    """The FE's label as a resonance list may carry it: a membrane label, or none for an air
    mode (``cavity(...)``: a peak the vibrometer sees but cannot name)."""
    return label if re.fullmatch(r"P\d+|\(\d+,\d+\)[ab]?", label) else ""


def _order(label: str) -> int:
    match = re.match(r"\((\d+),", label)
    return int(match.group(1)) if match else 0


def write_measured(case_name: str, seed: int, folder: Path, fe: FEModel | None = None) -> Path:
    """The case's measured set with noise of ``seed`` in ``folder``; its measured.yaml."""
    case = ALL_CASES[case_name]
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    base = dict(case.base)
    (folder / "base_study.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    conditions = []
    log_band = (math.log(BAND[0]), math.log(BAND[1]))
    for name, result in truth_modes(case, fe).items():
        rows = []
        for mode in result.modes:
            if _order(mode.label) > SEEN_ORDERS or rng.random() < P_MISS:
                continue
            frequency = mode.frequency_hz * math.exp(rng.normal(0.0, SCATTER))
            if not BAND[0] <= frequency <= BAND[1]:
                continue
            label = written_label(mode.label) if rng.random() < 0.5 else ""
            quality = ""
            if case.quality and mode.damping_ratio > 0:      # drawn after the label: the
                quality = f"{0.5 / mode.damping_ratio * math.exp(rng.normal(0.0, Q_SCATTER)):.4g}"
            rows.append((frequency, label, quality))        # other cases' draws unchanged
        for _ in range(rng.poisson(SPURIOUS)):
            rows.append((math.exp(rng.uniform(*log_band)), "", ""))
        rows.sort()
        path = folder / f"{name}_resonances.csv"
        if case.quality:
            path.write_text("freq_hz,label,quality_factor\n" + "".join(
                f"{f:.3f},{label},{q}\n" for f, label, q in rows))
        else:
            path.write_text("freq_hz,label\n" + "".join(f"{f:.3f},{label}\n"
                                                         for f, label, _ in rows))
        overrides = next(o for o in case.conditions if condition_name(o) == name)
        conditions.append({"name": name, "set": dict(overrides), "resonances": path.name,
                           "band": [f"{BAND[0]:g} Hz", f"{BAND[1]:g} Hz"]})
    manifest = {"name": f"{case_name}_seed{seed}",
                "description": f"FE-made data ({case_name}), seed {seed}",
                "base_study": "base_study.yaml",
                "noise": {"frequency_relative": SCATTER, "missing_probability": P_MISS,
                          "spurious_per_condition": SPURIOUS,
                          **({"quality_relative": Q_SCATTER} if case.quality else {})},
                "conditions": conditions}
    if case.candidates is not None:
        manifest["candidates"] = list(case.candidates)
    path = folder / "measured.yaml"
    path.write_text(yaml.safe_dump(manifest, sort_keys=False))
    return path


#: Set to 1: the tests may solve (and write) FE entries missing from the committed cache.
REFILL_VARIABLE = "COPDEA_FEM_FE_REFILL"


def battery_keys() -> set:
    """The cache keys of every FE study the battery fills (truth and base of every case)."""
    keys = set()
    for case in ALL_CASES.values():
        for raw in (case.truth, case.base):
            study = parse_study(raw, name="fe")
            keys |= {fe_key(fe_study(study.replace(o), BAND_MARGIN * BAND[1]))
                     for o in case.conditions}
    for case in DAMPING_CASES.values():        # the Prony probes of the material shares
        study = parse_study(case.base, name="fe")
        for o in case.conditions:
            for probe in prony_probes(study.replace(o)):
                keys.add(fe_key(fe_study(probe, BAND_MARGIN * BAND[1])))
    return keys


def prony_probes(study) -> list:
    """The FE studies of the material shares of ``study`` (the anchored engine's probes:
    :meth:`copdea_fem.diagnosis.anchored.AnchoredEngine.shares`)."""
    from copdea_fem.diagnosis.anchored import STRONG_PROBE, probe_study
    probe = probe_study(study)
    return [probe, probe.replace({"membrane.prony": [STRONG_PROBE]}),
            probe.replace({"membrane.prony": []})]


def missing_entries(cache: Path = FE_CACHE) -> list:
    """Battery keys with no entry in ``cache``: non-empty after a change to the FE code."""
    return sorted(key for key in battery_keys() if not (cache / f"{key}.json").is_file())


def stale_message(missing: list) -> str:
    return (f"tests/data/fe_cache is stale: {len(missing)} of its battery entries are missing "
            f"for the current FE code (copdea_fem.fingerprint.FE_SOURCES changed since it was "
            f"filled); refill it with `python tests/diagnosis/fe_battery.py --refill` "
            f"(measured: 36 min on two shared cores) or set {REFILL_VARIABLE}=1 to let the "
            f"tests solve what they miss")


def refill() -> None:
    """Empty the committed cache, fill the battery, then run the diagnosis tests with
    :data:`REFILL_VARIABLE` so that they write the other FE studies they ask for."""
    import os
    import subprocess
    import time
    start = time.perf_counter()
    for entry in FE_CACHE.glob("*.json"):
        entry.unlink()
    fill_side_by_side(list(ALL_CASES))
    root = Path(__file__).resolve().parent.parent.parent
    # the slow tests too (the ten-seed batteries ask for studies of their own), one
    # process per core (pytest-xdist); concurrent writers share entries by their locks
    tests = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                            "-m", "slow or not slow", "-n", "auto", "tests/diagnosis"],
                           cwd=root, env={**os.environ, REFILL_VARIABLE: "1"})
    print(f"{len(list(FE_CACHE.glob('*.json')))} entries in {FE_CACHE}, "
          f"{time.perf_counter() - start:.0f} s in all; the diagnosis tests "
          f"{'passed' if tests.returncode == 0 else 'FAILED (see above)'}")


def fill_side_by_side(keys) -> None:
    """:func:`fill` with one process per core, one case at a time per process (entries two
    cases share are solved once: :class:`FEModel` locks each entry)."""
    import os
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=min(len(keys), os.cpu_count() or 1)) as pool:
        for _ in pool.map(fill, [[key] for key in keys]):
            pass


def fill(keys) -> None:
    """Fill the FE cache of the named cases (truth and base at every condition)."""
    from copdea_fem.progress import progress_to
    model = FEModel(cache_dir=FE_CACHE)
    with progress_to(print, only_info=True):          # the FE progress lines
        for key in keys:
            truth_modes(ALL_CASES[key], model)
            base = ALL_CASES[key].base
            # the base's own FE (the model of record) at the same conditions
            truth_modes(Case(base, base, ALL_CASES[key].conditions, ()), model)
            if key in DAMPING_CASES:           # the Prony probes of the material shares
                study = parse_study(base, name="fe")
                for o in ALL_CASES[key].conditions:
                    for probe in prony_probes(study.replace(o)):
                        model.modes(probe, f_max=BAND_MARGIN * BAND[1])
    print(f"{model.solves} FE solves, {model.seconds:.0f} s")


def right(case_name: str, result) -> bool:
    """The case's right verdict: exactly its missing effects, nothing ambiguous."""
    case = ALL_CASES[case_name]
    return tuple(result.missing_effects) == case.missing and not result.ambiguous


if __name__ == "__main__":       # fill the FE cache of every case (or the named ones)
    if sys.argv[1:] == ["--refill"]:
        refill()
    else:
        fill(sys.argv[1:] or list(ALL_CASES))
