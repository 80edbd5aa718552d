"""Imperfections named from the split pairs of FE-made scans (docs/imperfections.md, "Split
pairs from a scan"): ``python -m benchmarks.split_pairs [--case NAME ...] [--f-max 1000]
[--conditions "load.z=16 mm, load.voltage=2 kV; ..."] [--keep DIR]``, or ``--blind N``: the
blind battery below.

Each case hides one imperfection in the G1 quick study (``studies/g1_z16_v2_quick.yaml``,
z = 16 mm, 2 kV, square frame, coupled with the air) and makes its scan as ``copdea-fem
synth --format uff`` does (the paper's grid, three components, 1.25 Hz lines to
``--f-max``, 60 dB, a 1.5 % frequency scatter shared by a pair's members, the case's seed);
``--conditions`` scans the device at each operating point given (``;`` between them; the
default one, 16 mm and 2 kV); the measured set is then diagnosed as a user would
(``cf.diagnose``) with the base study *without* the imperfection, ``identification:
{resolve_pairs: true}`` and ``pairing: {mac_min: 0.4}``.  Printed per case: the pairs the
diagnosis read (split, orientations; a lone member with its resolution), each
imperfection's fit, the verdict, and the seconds of the case.

``anisotropy``
    e = 2 % along 30 deg (seed 1).
``thickness``
    ``0.2 cos 2 (theta - 20 deg)`` (seed 2).
``mass``
    0.5 mg at r = 25 mm, theta = 45 deg (seed 3).

``--blind N [--kinds KIND ...] [--seeds S ...]`` hides, for each kind and N seeds (101,
102, ..., or the seeds S), one imperfection drawn at random from the seed - an anisotropy
e in 1-3 % along an axis in [0, 180) deg, an order-2 thickness term of amplitude 0.1-0.3 at
an angle in [0, 180) deg, a mass of 0.3-1 mg at r in 20-33 mm and theta in [0, 360) deg -
and N perfect devices, and counts per kind: named alone and right, ambiguous with the
truth among the group, named wrong, found round; the axis error of the fit of the true
kind (mod 180 deg, the mass's theta too: pair data cannot tell theta from theta + 180 deg).
"""

from __future__ import annotations

import argparse
import math
import shutil
import tempfile
import time
from pathlib import Path

import yaml

from benchmarks import ROOT

QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
CONDITION = "load.z=16 mm, load.voltage=2 kV"
CASES = {
    "anisotropy": ({"membrane.prestretch_anisotropy": 0.02,
                    "membrane.prestretch_axis": "30 deg"}, 1),
    "thickness": ({"membrane.thickness_variation": [
        {"order": 2, "amplitude": 0.2, "angle": "20 deg"}]}, 2),
    "mass": ({"imperfections.point_masses": [
        {"mass": "0.5 mg", "r": "25 mm", "theta": "45 deg"}]}, 3),
}


def run_case(name: str, folder: Path, f_max: float, conditions: str = CONDITION) -> dict:
    """One case (module doc): the diagnosis's ``imperfections`` entry and the seconds."""
    return run_hidden(*CASES[name], folder, f_max, conditions)


def run_hidden(overrides: dict, seed: int, folder: Path, f_max: float,
               conditions: str = CONDITION) -> dict:
    """The scan of the quick study with ``overrides`` hidden, diagnosed (module doc)."""
    import copdea_fem as cf
    from copdea_fem.diagnosis.synth_scan import ScanOptions

    started = time.perf_counter()
    cf.synthesise(cf.load_study(QUICK, overrides), conditions=conditions, file_format="uff",
                  options=ScanOptions(f_max=f_max, frequency_noise=0.015, seed=seed),
                  out=folder / "scan")
    measured_yaml = folder / "scan" / "measured.yaml"
    (folder / "scan" / "base_study.yaml").write_text(QUICK.read_text())
    manifest = yaml.safe_load(measured_yaml.read_text())
    manifest["identification"] = {"resolve_pairs": True}
    manifest["pairing"] = {"mac_min": 0.4}
    measured_yaml.write_text(yaml.safe_dump(manifest, sort_keys=False))
    diagnosis = cf.diagnose(measured_yaml, executor="inline", fe_cache=folder / "fe_cache")
    return {"imperfections": diagnosis.document["imperfections"],
            "seconds": time.perf_counter() - started}


def describe(name: str, result: dict) -> list[str]:
    """The lines printed for one case."""
    document = result["imperfections"]
    out = [(f"== {name} (hidden: {CASES[name][0]}, seed {CASES[name][1]}; "
            f"{result['seconds']:.0f} s)")]
    several = len({pair["condition"] for pair in document["pairs"]}) > 1
    for pair in document["pairs"]:
        where = f"{pair['condition']} " if several else ""
        if pair.get("lone_resolution") is not None:
            out.append(f"  {where}{pair['pair']}: one member at {pair['low_hz']:.2f} Hz, split < "
                       f"{100 * pair['lone_resolution']:.2f} %")
        else:
            angles = ("" if pair["low_orientation_deg"] is None else
                      f", axes {pair['low_orientation_deg']:.1f} / "
                      f"{pair['high_orientation_deg']:.1f} deg")
            out.append(f"  {where}{pair['pair']}: {pair['low_hz']:.2f} / {pair['high_hz']:.2f} Hz, "
                       f"split {100 * pair['split']:.3f} %{angles}")
    for effect, fit in document["fits"].items():
        values = ", ".join(f"{key} = {value:.4g}" for key, value in fit["values"].items()
                           if value is not None and math.isfinite(value))
        out.append(f"  fit {effect}: {values}; split deviance {fit['split_deviance']:.2f}, "
                   f"orientation deviance {fit['orientation_deviance']:.2f}")
    out.append(f"  verdict: {document['verdict']}")
    return out


#: The effect that names each blind kind, and the key of its fitted axis [deg] and period.
BLIND = {"anisotropy": ("anisotropic_prestretch", "axis", 180.0),
         "thickness": ("thickness_variation", "angle", 180.0),
         "mass": ("point_mass", "theta", 180.0), "round": (None, None, None)}
# (a mass at theta and at theta + 180 deg splits and orients every pair alike: the mode
# shapes' |phi|^2 has the period pi in theta, so pair data fix the mass's theta mod 180 deg)


def blind_case(kind: str, seed: int) -> tuple[dict, float | None]:
    """The overrides of one blind case drawn from ``seed`` (module doc), and its true axis."""
    import numpy as np

    rng = np.random.default_rng(seed)
    if kind == "anisotropy":
        e, axis = rng.uniform(0.01, 0.03), rng.uniform(0, 180)
        return ({"membrane.prestretch_anisotropy": round(float(e), 4),
                 "membrane.prestretch_axis": f"{axis:.2f} deg"}, round(float(axis), 2))
    if kind == "thickness":
        amplitude, angle = rng.uniform(0.1, 0.3), rng.uniform(0, 180)
        return ({"membrane.thickness_variation": [
            {"order": 2, "amplitude": round(float(amplitude), 3),
             "angle": f"{angle:.2f} deg"}]}, round(float(angle), 2))
    if kind == "mass":
        mass, r, theta = rng.uniform(0.3, 1.0), rng.uniform(20, 33), rng.uniform(0, 360)
        return ({"imperfections.point_masses": [
            {"mass": f"{mass:.3f} mg", "r": f"{r:.2f} mm", "theta": f"{theta:.2f} deg"}]},
            round(float(theta), 2))
    return {}, None


def blind_score(kind: str, truth_axis, document: dict) -> tuple[str, float | None]:
    """``right``, ``ambiguous`` (the truth in an undecided group), ``wrong`` or ``round``,
    and the axis error [deg] of the true kind's fit (None: round or not fitted)."""
    effect, key, period = BLIND[kind]
    named, groups = list(document["named"]), [list(g) for g in document["ambiguous"]]
    if effect is None:
        verdict = "round" if not named and not groups else "wrong"
    elif named == [effect]:
        verdict = "right"
    elif any(effect in group for group in groups):
        verdict = "ambiguous"
    else:
        verdict = "wrong" if named or groups else "round"
    fit = document["fits"].get(effect) if effect else None
    error = None
    if fit is not None and fit["values"].get(key) is not None:
        difference = (fit["values"][key] - truth_axis) % period
        error = min(difference, period - difference)
    return verdict, error


def run_blind(count: int, f_max: float, keep: Path | None,
              conditions: str = CONDITION, kinds=tuple(BLIND), seeds=None) -> None:
    """The blind battery (module doc) of ``kinds``: one line per case, a summary per kind;
    seeds 101 .. 100 + ``count``, or the ``seeds`` given (a rerun of some cases)."""
    from collections import Counter

    seeds = list(seeds) if seeds else list(range(101, 101 + count))
    summary = {}
    for kind in kinds:
        tally, errors = Counter(), []
        for seed in seeds:
            overrides, axis = blind_case(kind, seed)
            folder = (keep / f"{kind}_{seed}" if keep else
                      Path(tempfile.mkdtemp(prefix=f"copdea_blind_{kind}_")))
            folder.mkdir(parents=True, exist_ok=True)
            try:
                result = run_hidden(overrides, seed, folder, f_max, conditions)
            finally:
                if keep is None:
                    shutil.rmtree(folder, ignore_errors=True)
            verdict, error = blind_score(kind, axis, result["imperfections"])
            tally[verdict] += 1
            if error is not None and verdict in ("right", "ambiguous"):
                errors.append(error)
            print(f"{kind} seed {seed} ({overrides or 'round'}): {verdict}"
                  + (f", axis error {error:.2f} deg" if error is not None else "")
                  + f"; {result['imperfections']['verdict']} ({result['seconds']:.0f} s)",
                  flush=True)
        summary[kind] = (tally, errors)
    for kind, (tally, errors) in summary.items():
        print(f"{kind}: {dict(tally)} of {len(seeds)}"
              + (f"; axis error max {max(errors):.2f} deg" if errors else ""))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", nargs="+", choices=sorted(CASES), default=list(CASES))
    parser.add_argument("--f-max", type=float, default=1000.0, help="top of the scan [Hz]")
    parser.add_argument("--conditions", default=CONDITION,
                        help="the operating points scanned, ';' between them (default: "
                             f"'{CONDITION}')")
    parser.add_argument("--kinds", nargs="+", choices=list(BLIND), default=list(BLIND),
                        help="the blind battery's kinds (default: all)")
    parser.add_argument("--keep", type=Path, help="keep the scans and FE caches here")
    parser.add_argument("--blind", type=int, metavar="N",
                        help="the blind battery: N seeds of each kind and N round devices")
    parser.add_argument("--seeds", type=int, nargs="+", metavar="S",
                        help="the blind battery's seeds (default: 101 .. 100 + N)")
    args = parser.parse_args(argv)
    if args.seeds is not None:
        if args.blind is not None:
            parser.error("--blind and --seeds: give one (--seeds S ... runs those seeds)")
        if any(seed < 0 for seed in args.seeds):
            parser.error(f"--seeds = {args.seeds} is not allowed; allowed: integers >= 0")
        args.blind = len(args.seeds)
    if args.blind is not None:
        if args.blind < 1:
            parser.error(f"--blind = {args.blind} is not allowed; allowed: an integer >= 1")
        run_blind(args.blind, args.f_max, args.keep, args.conditions, args.kinds, args.seeds)
        return
    for name in args.case:
        folder = (args.keep / name if args.keep else
                  Path(tempfile.mkdtemp(prefix=f"copdea_split_pairs_{name}_")))
        folder.mkdir(parents=True, exist_ok=True)
        try:
            print("\n".join(describe(name, run_case(name, folder, args.f_max,
                                                     args.conditions))), flush=True)
        finally:
            if args.keep is None:
                shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
