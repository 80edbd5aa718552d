"""The error of bad measured data, raised by every reader of :mod:`copdea_fem.measured`."""

from __future__ import annotations

from typing import Any

from copdea_fem.study import StudyError
from copdea_fem.study.keys import refusal as study_refusal


class MeasuredDataError(StudyError):
    """Bad measured data: the message names the file or key, the value and what is allowed.

    A :class:`~copdea_fem.study.StudyError`, hence a ``ValueError`` (the CLI's exit 2).
    """


def refusal(key: str, value: Any, allowed: str, why: str = "") -> MeasuredDataError:
    """The :class:`MeasuredDataError` refusing ``key = value``: ``why`` (if given) and what
    is ``allowed`` (the message of :func:`copdea_fem.study.keys.refusal`)."""
    return MeasuredDataError(str(study_refusal(key, value, allowed, why)))


__all__ = ["MeasuredDataError", "refusal"]
