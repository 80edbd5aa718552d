"""Gathering the points: mode tracking, the long table sweep.csv, sweep.json, the summary."""

from __future__ import annotations

import csv
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from copdea_fem.sweeps.plots import plot_sweep
from copdea_fem.sweeps.spec import Sweep
from copdea_fem.sweeps.store import PointStore, json_default
from copdea_fem.sweeps.tracking import ModeSet, track_modes

TABLE_COLUMNS = ("point", "status", "track", "track_label", "member", "pair", "label", "m", "n",
                 "kind", "freq_hz", "freq_im_hz", "mac_previous", "error")


logger = logging.getLogger(__name__)


@dataclass
class SweepOutcome:
    """What :func:`copdea_fem.sweeps.executors.run_sweep` did."""

    directory: Path
    table: list
    computed: list
    resumed: list
    failed: dict
    wall_seconds: float
    tracks: dict


def finish_sweep(sweep: Sweep, directory: str | Path) -> SweepOutcome:
    """Track the stored results along the path; write sweep.csv, sweep.png, resolved YAML."""
    directory = Path(directory)
    store = PointStore(directory)
    records = {pid: store.record(pid) for pid in sweep.path}
    sets = []
    for pid in sweep.path:
        record = records[pid]
        if store.finished(sweep.point(pid)):
            arrays = store.arrays(pid)
            modes = record["modes"]
            sets.append(ModeSet(
                freq_hz=[m["freq_hz"] for m in modes], labels=[m["label"] for m in modes],
                kinds=[m["kind"] for m in modes], m=[m["m"] for m in modes],
                vectors=arrays.get("vectors"), weighted=arrays.get("weighted"),
                space=record.get("space"), sampled=arrays.get("sampled")))
        else:
            sets.append(ModeSet(np.zeros(0), [], [], np.zeros(0, int)))
    tracking = track_modes(sets, sweep.tracking)
    path_position = {pid: i for i, pid in enumerate(sweep.path)}
    rows, failed = [], {}
    for point in sweep.points:
        record = records[point.point_id]
        parameters = {axis.column(): point.overrides[axis.key] for axis in sweep.axes}
        base_row = {"point": point.point_id, **parameters}
        if not record or record.get("study_hash") != point.study_hash or \
                (record["status"] == "ok" and not store.finished(point)):
            rows.append({**base_row, "status": "missing"})
            failed[point.point_id] = "not computed"
            continue
        if record["status"] != "ok":
            rows.append({**base_row, "status": "failed", "error": record.get("error", "")})
            failed[point.point_id] = record.get("error", "")
            continue
        p = path_position[point.point_id]
        order = np.argsort([m["freq_hz"] for m in record["modes"]], kind="stable")
        for k in order:
            mode = record["modes"][k]
            track = int(tracking.track[p][k])
            mac = tracking.mac_previous[p][k]
            rows.append({**base_row, "status": "ok", "track": track,
                         "track_label": tracking.labels[track],
                         "member": int(tracking.member[p][k]),
                         "pair": bool(tracking.unit_size[p][k] == 2), "label": mode["label"],
                         "m": mode["m"], "n": mode["n"], "kind": mode["kind"],
                         "freq_hz": mode["freq_hz"], "freq_im_hz": mode.get("freq_im_hz", 0.0),
                         "mac_previous": "" if math.isnan(mac) else round(float(mac), 6),
                         "error": ""})
    columns = ["point"] + [axis.column() for axis in sweep.axes] + list(TABLE_COLUMNS[1:])
    directory.mkdir(parents=True, exist_ok=True)
    _write_csv(directory / "sweep.csv", rows, columns)
    (directory / "sweep.resolved.yaml").write_text(yaml.safe_dump(
        json.loads(json.dumps(sweep.resolved(), default=json_default)), sort_keys=False))
    if sweep.plots:
        plot_sweep(directory / "sweep.png", sweep, rows)
    if failed:
        for point_id, error in failed.items():
            logger.info(f"point {point_id} has no result: {error}")
    return SweepOutcome(directory=directory, table=rows, computed=[], resumed=[], failed=failed,
                        wall_seconds=0.0, tracks=dict(tracking.labels))


def _write_csv(path: Path, rows: list[dict], columns: list[str]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({c: _csv_value(row.get(c, "")) for c in columns})
    tmp.replace(path)


def _csv_value(value):
    if isinstance(value, float):
        return repr(value)
    return value


def read_table(path: str | Path) -> list[dict]:
    """The rows of a ``sweep.csv`` as dicts of strings."""
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def write_summary(sweep: Sweep, directory: Path, outcome: SweepOutcome) -> None:
    store = PointStore(directory)
    points = []
    for point_id in sweep.path:
        record = store.record(point_id) or {}
        points.append({"point": point_id, "parameters": sweep.point(point_id).overrides,
                       "status": record.get("status", "missing"),
                       "error": record.get("error"), "timings_s": record.get("timings_s"),
                       "reuse": record.get("reuse"), "eigen": record.get("eigen"),
                       "prestress": record.get("prestress"), "worker": record.get("worker"),
                       "computed_now": point_id in outcome.computed})
    document = {"name": sweep.name, "model": sweep.model, "path": sweep.path,
                "wall_s": outcome.wall_seconds, "computed": outcome.computed,
                "resumed": outcome.resumed, "failed": outcome.failed,
                "tracks": {str(k): v for k, v in outcome.tracks.items()}, "points": points}
    tmp = directory / "sweep.json.tmp"
    tmp.write_text(json.dumps(document, indent=1, default=json_default))
    tmp.replace(directory / "sweep.json")


def format_summary(sweep: Sweep, outcome: SweepOutcome, max_columns: int = 12) -> str:
    """Tracked modes of the plotted kinds as text: one row per track, one column per point.

    Single-axis sweeps with at most ``max_columns`` points get the frequency at every
    point [Hz]; otherwise each track's range.
    """
    rows = [row for row in outcome.table if row.get("status") == "ok"]
    shown = sorted({row["track"] for row in rows if row["kind"] in sweep.plot_kinds})
    axis = sweep.axes[0]
    lines = []
    if len(sweep.axes) == 1 and len(axis.values) <= max_columns:
        column = axis.column()
        header = "".join(f"{axis.format(v).split()[0]:>9}" for v in axis.values)
        lines.append(f"{'track':>5}  {'label':<14}{header}   <- {axis.label()}")
        for track in shown:
            by_value: dict = {}
            for row in rows:
                if row["track"] == track:
                    by_value.setdefault(row[column], []).append(row["freq_hz"])
            cells = "".join(f"{np.mean(by_value[v]):9.2f}" if v in by_value else f"{'-':>9}"
                            for v in axis.values)
            lines.append(f"{track:>5}  {outcome.tracks[track]:<14}{cells}")
        lines.append(f"{'':>5}  {'':<14}{'[Hz]':>9}")
    else:
        for track in shown:
            freqs = [row["freq_hz"] for row in rows if row["track"] == track]
            lines.append(f"{track:>5}  {outcome.tracks[track]:<14}{min(freqs):9.2f} .."
                         f"{max(freqs):9.2f} Hz at {len(freqs)} rows")
    for point_id, error in outcome.failed.items():
        lines.append(f"point {point_id} failed: {error}")
    lines.append(f"{len(sweep.points)} points ({len(outcome.computed)} computed, "
                 f"{len(outcome.resumed)} resumed, {len(outcome.failed)} without result) in "
                 f"{outcome.wall_seconds:.1f} s; results in {outcome.directory}")
    return "\n".join(lines)
