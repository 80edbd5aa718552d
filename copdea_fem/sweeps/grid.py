"""The grid of a sweep: its points, their keys (context, space) and the continuation path."""

from __future__ import annotations

import hashlib
import itertools
import json

import numpy as np

from copdea_fem.fe import check_air_lift, engine_for
from copdea_fem.fingerprint import model_fingerprint
from copdea_fem.study import Study, StudyError
from copdea_fem.sweeps.axes import (
    LOAD_LIKE_SECTIONS,
    MAX_POINTS,
    Axis,
    SweepError,
    SweepPoint,
    sweep_error,
)


def content_hash(data) -> str:
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def _context_key(study: Study, model: str) -> str:
    """Points with equal keys can share a mesh and continue one membrane solver."""
    values = {section: keys for section, keys in study.values.items()
              if section not in LOAD_LIKE_SECTIONS}
    return content_hash({"model": model, **values})


def _space_key(study: Study, model: str, engine) -> str:
    """Points with equal keys have shape vectors in the same basis (MAC by mass matrix):
    the ring model's, or the FE space of the point's engine
    (:meth:`copdea_fem.fe.engines.Engine.space_key`)."""
    if model == "reduced":
        return f"rings:{study.reduced.rings}:{study.disc.motion}"
    return engine.space_key(study, with_air=model == "coupled")


def expand_grid(base: Study, axes: list[Axis], model: str) -> list[SweepPoint]:
    """Every grid point (row-major over the axes as given), validated before any solve."""
    shape = [len(axis.values) for axis in axes]
    total = int(np.prod(shape))
    if total > MAX_POINTS:
        raise sweep_error("axes", f"{total} points", f"at most {MAX_POINTS} grid points")
    width = max(3, len(str(total - 1)))
    points = []
    for number, index in enumerate(itertools.product(*(range(n) for n in shape))):
        overrides = {axis.key: axis.values[i] for axis, i in zip(axes, index)}
        if model == "coupled":
            overrides.setdefault("air.enabled", True)
        try:
            study = base.replace(overrides, name=f"{base.name}/p{number:0{width}d}")
            if model == "coupled":
                check_air_lift(study)
        except StudyError as error:
            where = ", ".join(f"{a.key} = {a.values[i]!r}" for a, i in zip(axes, index))
            raise SweepError(f"grid point p{number:0{width}d} ({where}): {error}") from None
        if model == "dry" and study.air.enabled:
            raise sweep_error("air.enabled", True, "false with model: dry (model: coupled couples "
                              "the air)", f"grid point p{number:0{width}d}")
        engine = None if model == "reduced" else engine_for(study)
        hashed = {s: v for s, v in study.values.items() if s != "output"}
        # a finished point is resumed only under the code that computed it
        hashed["code"] = model_fingerprint(model)
        points.append(SweepPoint(point_id=f"p{number:0{width}d}", index=tuple(index),
                                 overrides=overrides, study=study,
                                 context_key=_context_key(study, model),
                                 space_key=_space_key(study, model, engine),
                                 study_hash=content_hash({"model": model, **hashed}),
                                 engine=engine))
    return points


def continuation_path(points: list[SweepPoint], axes: list[Axis]) -> list[str]:
    """Context-changing axes outermost, then a serpentine: neighbours differ by one step."""
    order = [i for i, a in enumerate(axes) if a.changes_context] + \
        [i for i, a in enumerate(axes) if not a.changes_context]

    def serpentine(point: SweepPoint):
        key, flips = [], 0
        for i in order:
            position = point.index[i]
            count = len(axes[i].values)
            key.append(count - 1 - position if flips % 2 else position)
            flips += key[-1]
        return tuple(key)

    return [p.point_id for p in sorted(points, key=serpentine)]
