"""Imperfections named from the split pairs of FE-made scans (docs/imperfections.md, "Split
pairs from a scan"): ``python -m benchmarks.split_pairs [--case NAME ...] [--f-max 1000]
[--keep DIR]``.

Each case hides one imperfection in the G1 quick study (``studies/g1_z16_v2_quick.yaml``,
z = 16 mm, 2 kV, square frame, coupled with the air) and makes its scan as ``copdea-fem
synth --format uff`` does (the paper's grid, three components, 1.25 Hz lines to
``--f-max``, 60 dB, a 1.5 % frequency scatter shared by a pair's members, the case's seed);
the measured set is then diagnosed as a user would (``cf.diagnose``) with the base study
*without* the imperfection, ``identification: {resolve_pairs: true}`` and ``pairing:
{mac_min: 0.4}``.  Printed per case: the pairs the diagnosis read (split, orientations; a
lone member with its resolution), each imperfection's fit, the verdict, and the seconds
of the case.

``anisotropy``
    e = 2 % along 30 deg (seed 1).
``thickness``
    ``0.2 cos 2 (theta - 20 deg)`` (seed 2).
``mass``
    0.5 mg at r = 25 mm, theta = 45 deg (seed 3).
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


def run_case(name: str, folder: Path, f_max: float) -> dict:
    """One case (module doc): the diagnosis's ``imperfections`` entry and the seconds."""
    import copdea_fem as cf
    from copdea_fem.diagnosis.synth_scan import ScanOptions

    overrides, seed = CASES[name]
    started = time.perf_counter()
    cf.synthesise(cf.load_study(QUICK, overrides), conditions=CONDITION, file_format="uff",
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
    for pair in document["pairs"]:
        if pair.get("lone_resolution") is not None:
            out.append(f"  {pair['pair']}: one member at {pair['low_hz']:.2f} Hz, split < "
                       f"{100 * pair['lone_resolution']:.2f} %")
        else:
            angles = ("" if pair["low_orientation_deg"] is None else
                      f", axes {pair['low_orientation_deg']:.1f} / "
                      f"{pair['high_orientation_deg']:.1f} deg")
            out.append(f"  {pair['pair']}: {pair['low_hz']:.2f} / {pair['high_hz']:.2f} Hz, "
                       f"split {100 * pair['split']:.3f} %{angles}")
    for effect, fit in document["fits"].items():
        values = ", ".join(f"{key} = {value:.4g}" for key, value in fit["values"].items()
                           if value is not None and math.isfinite(value))
        out.append(f"  fit {effect}: {values}; split deviance {fit['split_deviance']:.2f}, "
                   f"orientation deviance {fit['orientation_deviance']:.2f}")
    out.append(f"  verdict: {document['verdict']}")
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", nargs="+", choices=sorted(CASES), default=list(CASES))
    parser.add_argument("--f-max", type=float, default=1000.0, help="top of the scan [Hz]")
    parser.add_argument("--keep", type=Path, help="keep the scans and FE caches here")
    args = parser.parse_args(argv)
    for name in args.case:
        folder = (args.keep / name if args.keep else
                  Path(tempfile.mkdtemp(prefix=f"copdea_split_pairs_{name}_")))
        folder.mkdir(parents=True, exist_ok=True)
        try:
            print("\n".join(describe(name, run_case(name, folder, args.f_max))), flush=True)
        finally:
            if args.keep is None:
                shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
