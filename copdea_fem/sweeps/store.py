"""Point folders on disk: one atomically written result per point, resumable."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from copdea_fem.sweeps.models import PointResult
from copdea_fem.sweeps.spec import SweepPoint


class PointStore:
    """``OUT/points/<id>/result.json`` (+ ``vectors.npz``), each point written atomically."""

    def __init__(self, directory: str | Path):
        self.root = Path(directory) / "points"

    def record(self, point_id: str) -> dict | None:
        path = self.root / point_id / "result.json"
        if not path.is_file():
            return None
        try:
            return json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            return None

    def finished(self, point: SweepPoint) -> bool:
        record = self.record(point.point_id)
        return bool(record) and record.get("status") == "ok" and \
            record.get("study_hash") == point.study_hash and \
            (self.root / point.point_id / "vectors.npz").is_file()

    def write(self, result: PointResult) -> None:
        from copdea_fem.folders import result_directory
        self.root.mkdir(parents=True, exist_ok=True)
        with result_directory(self.root / result.point_id, "sweep point") as staging:
            if result.arrays:
                # float32 halves the files; the MAC needs ~1e-6, float32 gives ~1e-7
                np.savez(staging / "vectors.npz",
                         **{k: _compact(v) for k, v in result.arrays.items()})
            (staging / "result.json").write_text(json.dumps(result.record, indent=1,
                                                            default=json_default))

    def arrays(self, point_id: str) -> dict:
        with np.load(self.root / point_id / "vectors.npz") as data:
            return {key: data[key] for key in data.files}


def _compact(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array)
    return array.astype(np.complex64 if np.iscomplexobj(array) else np.float32)


def json_default(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)
