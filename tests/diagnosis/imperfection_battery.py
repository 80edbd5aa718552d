"""Blind battery of the imperfection stage on FE-made data (issue 44, item 5).

Each case hides one imperfection (or none) in G1 at z = 16 mm, V_b = 2 kV in vacuo: the
"measured" pairs are the 3-D FE's modes of the device with the hidden keys
(:func:`copdea_fem.fe.pipeline.dry_modes` on the study the diagnosis's FE would solve,
:func:`copdea_fem.diagnosis.fe.fe_study`, on the 3-D engine also for a perfect device), with a common 1 % log-normal scale per condition
(a model error that cancels in a split), each member's frequency scattered by
``SPLIT_SIGMA / sqrt 2`` (log-normal) and each orientation by 3 deg (a scan's), the pairs
of m <= 3 in the band [5 Hz, 1.2 kHz] kept ((m,1) and the (1,2) pair).  The diagnosis gets the measured.yaml (base
study without any imperfection) and the pairs, never the truth; its trial FE solves go to
the cache folder given (never tests/data/fe_cache).

    python tests/diagnosis/imperfection_battery.py --seeds 1 2 3 --cache /tmp/imp_cache

prints one line per case and the share named right (and, from the same data without the
orientations, the share whose effect alone is named from the resonance list) (the right effect alone, its angle
within 10 deg modulo the period the data can tell: 180 deg for an axis and a mass, 360/k
for an order-k term; for a thickness term, the right order) and the false imperfections
on perfect devices.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np
import yaml

KINDS = ("anisotropic_prestretch", "thickness_variation", "point_mass", "perfect")
BAND = (5.0, 1200.0)
M_MAX = 3
ORIENTATION_NOISE_DEG = 3.0
COMMON_NOISE = 0.01


def base_raw(membrane_size: str = "6 mm") -> dict:
    """G1 (Table 1) at z = 16 mm, V_b = 2 kV, in vacuo, frame none, coarse 3-D mesh."""
    return {"name": "g1_imperfect_battery",
            "geometry": {"inner_radius": "17 mm", "frame": "none"},
            "disc": {"mass": "3.0 g"}, "load": {"z": "16 mm", "voltage": "2 kV"},
            "mesh": {"membrane_size": membrane_size}, "eigen": {"f_max": "1200 Hz"}}


def draw_truth(kind: str, rng, study) -> dict:
    """The hidden imperfection's study overrides (module notes' ranges)."""
    r_i, r_o = study.geometry.inner_radius, study.geometry.outer_radius
    if kind == "anisotropic_prestretch":
        return {"membrane.prestretch_anisotropy": float(rng.uniform(0.005, 0.03)),
                "membrane.prestretch_axis": float(rng.uniform(0, 180))}
    if kind == "thickness_variation":
        order = int(rng.choice([2, 4]))
        return {"membrane.thickness_variation": [
            {"order": order, "amplitude": float(rng.uniform(0.1, 0.4)),
             "angle": float(rng.uniform(0, 360 / order))}]}
    if kind == "point_mass":
        return {"imperfections.point_masses": [
            {"mass": float(rng.uniform(0.25e-6, 1.0e-6)),
             "r": float(r_i + rng.uniform(0.2, 0.85) * (r_o - r_i)),
             "theta": float(rng.uniform(0, 360))}]}
    return {}


def fe_made_pairs(study, condition: str, rng, band=BAND):
    """The measured resonances and pairs of ``study`` (with the hidden keys) from its 3-D FE
    modes (module notes)."""
    from copdea_fem.diagnosis.fe import BAND_MARGIN, fe_study
    from copdea_fem.diagnosis.imperfections import LABEL, SPLIT_SIGMA, ObservedPair
    from copdea_fem.fe import engine_for
    from copdea_fem.fe.pipeline import dry_modes
    from copdea_fem.measured import Resonance

    # the 3-D engine whatever the device (a perfect one too: its mesh's own splits)
    run = fe_study(study, BAND_MARGIN * band[1]).replace({"mesh.engine": "3d"})
    _, modes, _ = dry_modes(run, engine=engine_for(run))
    scale = math.exp(rng.normal(0, COMMON_NOISE))
    members, resonances = {}, []
    for mode in modes:
        if mode.kind != "out-of-plane" or not mode.label or not band[0] <= mode.freq_hz <= band[1]:
            continue
        if mode.m > M_MAX:
            continue
        f = mode.freq_hz * scale * math.exp(rng.normal(0, SPLIT_SIGMA / math.sqrt(2)))
        if not LABEL.match(mode.label):          # a second mode of one (m,n) ("(0,2)-2"):
            resonances.append(Resonance(f, ""))  # a lab would not label it either
            continue
        resonances.append(Resonance(f, mode.label))
        if mode.m >= 1:
            angle = (mode.orientation_deg + rng.normal(0, ORIENTATION_NOISE_DEG)) % (180 / mode.m)
            members.setdefault((mode.label[:-1], mode.m), []).append((f, angle))
    pairs = []
    for (label, m), found in sorted(members.items()):
        if len(found) == 2:
            (f_low, a_low), (f_high, a_high) = sorted(found)
            pairs.append(ObservedPair(condition, label, m, f_low, f_high, a_low, a_high))
    return sorted(resonances, key=lambda r: r.frequency_hz), pairs


def write_set(folder: Path, raw: dict, resonances, band=BAND) -> Path:
    """measured.yaml, base_study.yaml (no imperfection) and the resonance list."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base_study.yaml").write_text(yaml.safe_dump(raw))
    lines = ["freq_hz,label"] + [f"{r.frequency_hz:.6f},{r.label}" for r in resonances]
    (folder / "z16_v2_resonances.csv").write_text("\n".join(lines) + "\n")
    manifest = {"name": "imperfection_battery", "base_study": "base_study.yaml", "model": "fe",
                "conditions": [{"name": "z16_v2", "set": {"load.z": "16 mm",
                                                          "load.voltage": "2 kV"},
                                "resonances": "z16_v2_resonances.csv",
                                "band": [f"{band[0]:g} Hz", f"{band[1]:g} Hz"]}]}
    path = folder / "measured.yaml"
    path.write_text(yaml.safe_dump(manifest))
    return path


def angle_error(fitted: float, true: float, period: float) -> float:
    return abs((fitted - true + 0.5 * period) % period - 0.5 * period)


def judge(kind: str, truth: dict, verdict) -> tuple[bool, float]:
    """Whether the verdict names ``kind`` right (module notes) and the angle error [deg]."""
    if kind == "perfect":
        return (not verdict.named and not verdict.ambiguous), math.nan
    if verdict.named != (kind,):
        return False, math.nan
    values = verdict.fits[kind].values
    if kind == "anisotropic_prestretch":
        error = angle_error(values[1], truth["membrane.prestretch_axis"], 180.0)
    elif kind == "thickness_variation":
        term = truth["membrane.thickness_variation"][0]
        if round(values[0]) != term["order"]:
            return False, math.nan
        error = angle_error(values[2], term["angle"], 360.0 / term["order"])
    else:
        error = angle_error(values[2], truth["imperfections.point_masses"][0]["theta"], 180.0)
    return error <= 10.0, error


def run_case(kind: str, seed: int, folder: Path, fe, with_orientations: bool = True,
             membrane_size: str = "6 mm", band=BAND, reuse: bool = False) -> dict:
    """One blind case: data made (or, with ``reuse``, read from the case's fe_made.json of
    an earlier run), diagnosed, judged."""
    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.imperfections import ObservedPair, name_imperfections
    from copdea_fem.measured import Resonance
    from copdea_fem.study import parse_study

    rng = np.random.default_rng(1000 * seed + KINDS.index(kind))
    raw = base_raw(membrane_size)
    base = parse_study(raw, name=raw["name"])
    truth = draw_truth(kind, rng, base)
    saved = folder / f"{kind}_{seed}" / "fe_made.json"
    if reuse and saved.is_file():           # the same case's FE-made data, made before
        document = json.loads(saved.read_text())
        resonances = [Resonance(*r) for r in document["resonances"]]
        pairs = [ObservedPair(*p) for p in document["pairs"]]
    else:
        resonances, pairs = fe_made_pairs(base.replace(truth), "z16_v2", rng, band)
        saved.parent.mkdir(parents=True, exist_ok=True)
        saved.write_text(json.dumps({"truth": truth,
                                     "resonances": [[r.frequency_hz, r.label] for r in resonances],
                                     "pairs": [dataclasses.astuple(p) for p in pairs]}))
    measured = load_measured(write_set(folder / f"{kind}_{seed}", raw, resonances, band))
    verdict = name_imperfections(measured, fe, pairs=pairs if with_orientations else None)
    right, error = judge(kind, truth, verdict)
    # the same data without the orientations: the resonance list alone
    alone = name_imperfections(measured, fe) if with_orientations else verdict
    return {"kind": kind, "seed": seed, "truth": truth, "verdict": verdict, "right": right,
            "angle_error": error, "frequencies_only": alone,
            "named_from_frequencies": alone.named == ((kind,) if kind != "perfect" else ())
            and not alone.ambiguous}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    parser.add_argument("--cache", type=Path, required=True)
    parser.add_argument("--out", type=Path, default=Path("/tmp/imperfection_battery"))
    parser.add_argument("--reuse", action="store_true",
                        help="read each case's FE-made data from an earlier run's --out")
    parser.add_argument("--frequencies-only", action="store_true",
                        help="no orientations: the resonance lists alone")
    args = parser.parse_args(argv)
    from copdea_fem.diagnosis.fe import FEModel
    fe = FEModel(cache_dir=args.cache, workers=1)
    tally = {}
    for kind in args.kinds:
        for seed in args.seeds:
            case = run_case(kind, seed, args.out, fe, not args.frequencies_only,
                            reuse=args.reuse)
            tally.setdefault(kind, []).append((case["right"], case["named_from_frequencies"]))
            print(f"{kind:24s} seed {seed}: {'RIGHT' if case['right'] else 'wrong'} "
                  f"angle error {case['angle_error']:.1f} deg | truth {case['truth']} | "
                  f"{case['verdict'].verdict} | frequencies only: "
                  f"{case['frequencies_only'].verdict}", flush=True)
    for kind, rights in tally.items():
        print(f"{kind}: {sum(r for r, _ in rights)}/{len(rights)} right with orientations; "
              f"{sum(f for _, f in rights)}/{len(rights)} named right from the frequencies "
              "alone (no angle)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
