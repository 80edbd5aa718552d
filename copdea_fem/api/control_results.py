"""Selective excitation and control models: the drive that lights a mode (:func:`excite`,
:class:`Excitation`) and the device as a real LTI system (:func:`statespace`,
:class:`StateSpace`), both from the band's coupled modes driven by the study's inputs
(:mod:`copdea_fem.forced_response.modal_inputs`)."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from copdea_fem.api.calls import as_study, check_size, input_files, reporting_to, solving
from copdea_fem.api.folders import Output, claimed, claiming
from copdea_fem.folders import Claim
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    import pandas as pd

    from copdea_fem.forced_response.excitation import ExcitationDesign
    from copdea_fem.forced_response.modal_inputs import ModalInputs
    from copdea_fem.forced_response.statespace import StateSpaceModel

logger = logging.getLogger("copdea_fem")

#: Lines of the spectra plot of ``excite`` [per Hz of the band].
SPECTRUM_LINES = 2000


def _modal_model(study: Study, allow_large: bool, timings: dict, microphones=()):
    """The solve of ``study`` and its modal model for the study's inputs at its points (and
    ``microphones``: :func:`copdea_fem.forced_response.statespace.statespace_microphones`)."""
    from copdea_fem.fe import engine_for, run_solve
    from copdea_fem.forced_response.modal_inputs import ModalInputs, drive_inputs, study_points

    engine = engine_for(study)
    check_size(study, allow_large, engine)
    start = time.perf_counter()
    with solving(study):
        solution = run_solve(study, engine=engine)
    timings["solve"] = time.perf_counter() - start
    start = time.perf_counter()
    names, positions = study_points(solution, study)
    model = ModalInputs.build(solution, study, drive_inputs(study), positions, names,
                              microphones)
    timings["modal model"] = time.perf_counter() - start
    return solution, model


def excite(study: Study | str | Path, targets: Sequence[str], *, max_ac: float | None = None,
           allow_large: bool = False, progress: Callable[[str], None] | None = None,
           out: str | Path | Claim | Output | None = None) -> Excitation:
    """The drive of each input that makes the target mode(s) respond while the other
    out-of-plane modes of the band stay as small as the inputs allow (``copdea-fem excite``;
    the criterion: :mod:`copdea_fem.forced_response.excitation`).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file (``load.voltage`` > 0).
    targets : sequence of str
        Mode labels of the band (``(2,1)a``; a pair's stem ``(2,1)`` means its first member).
    max_ac : float, optional
        Peak AC amplitude of the drive [V] (default: ``excitation.amplitude``), > 0.
    allow_large, progress, out
        As :func:`solve`'s.

    Returns
    -------
    Excitation

    Raises
    ------
    StudyError
        A bad study, ``load.voltage = 0``, no target, ``max_ac`` <= 0, a target that is not a
        mode of the band (the message lists the band's labels) or that no input drives.
    SolveFailed, PrestressError, OutputFolderError
        As :func:`solve`.
    """
    import numpy as np
    from copdea_fem.forced_response.excitation import design_drive
    from copdea_fem.forced_response.statespace import check_statespace_study

    study = as_study(study)
    targets = list(targets or [])
    if not targets:
        raise StudyError("--target is required for `excite`; allowed: one or more mode "
                         "labels of the band, e.g. --target '(2,1)'")
    amplitude = float(study.excitation.amplitude if max_ac is None else max_ac)
    if not np.isfinite(amplitude) or amplitude <= 0:
        raise StudyError(f"--max-ac = {max_ac!r} is not allowed; allowed: a peak AC "
                         "amplitude > 0 V")
    check_statespace_study(study)
    timings: dict = {}
    with claiming(out, "excite", input_files(study), study.output.directory) as folder:
        with reporting_to(progress):
            _, model = _modal_model(study, allow_large, timings)
            start = time.perf_counter()
            design = design_drive(model, targets, amplitude, study.eigen.f_max)
            timings["design"] = time.perf_counter() - start
            for line in design.inseparable:
                logger.warning(line)
        result = Excitation(study, model, design, timings)
        if folder is not None:
            result.write(folder, progress)
    return result


class Excitation:
    """The result of :func:`excite`: the drive, the selectivity, ``write``.

    Parameters
    ----------
    study : Study
    model : ModalInputs
    design : ExcitationDesign
    timings : dict
    """

    def __init__(self, study: Study, model: ModalInputs, design: ExcitationDesign,
                 timings: dict) -> None:
        self.study, self.model, self.design, self.timings = study, model, design, timings

    @property
    def drive(self) -> pd.DataFrame:
        """``drive.csv``: ``segment, amplitude, phase_deg`` [-, V, deg]."""
        import pandas as pd

        from copdea_fem.forced_response.excitation import DRIVE_COLUMNS
        d = self.design
        return pd.DataFrame(dict(zip(DRIVE_COLUMNS, (d.inputs, d.amplitude, d.phase_deg))))

    @property
    def selectivity(self) -> pd.DataFrame:
        """``selectivity.csv``: ``label, freq_hz, level_db`` [-, Hz, dB re the target]."""
        import pandas as pd

        from copdea_fem.forced_response.excitation import SELECTIVITY_COLUMNS
        d = self.design
        return pd.DataFrame(dict(zip(SELECTIVITY_COLUMNS, (d.labels, d.freq_hz, d.level_db))))

    def set_lines(self) -> list[str]:
        """The ``--set`` lines that feed the drive to ``copdea-fem response``."""
        from copdea_fem.forced_response.excitation import set_lines
        return set_lines(self.design, self.study)

    def spectra(self, frequency_hz=None):
        """(lines [Hz], the modulus of v averaged over the points and components [m/s] of the inputs
        driven together at ``max_ac`` in phase (one electrode), of the designed drive)."""
        import numpy as np
        f_max = float(self.study.eigen.f_max)
        if frequency_hz is None:
            frequency_hz = np.linspace(f_max / SPECTRUM_LINES, f_max, SPECTRUM_LINES)
        velocity, _ = self.model.frequency_response(frequency_hz)
        peak = float(np.abs(self.design.drive).max())
        single = np.abs(velocity.sum(axis=-1) * peak).mean(axis=(1, 2))
        designed = np.abs(velocity @ np.conj(self.design.drive)).mean(axis=(1, 2))
        return np.asarray(frequency_hz), single, designed

    def summary_lines(self) -> list[str]:
        import numpy as np
        d = self.design
        lines = [f"{self.study.name}: drive of {len(d.inputs)} input(s) for "
                 + ", ".join(d.targets) + f" (peak {np.abs(d.drive).max():g} V)"]
        lines += [f"{name:>12} {amplitude:9.3f} V {phase:8.2f} deg"
                  for name, amplitude, phase in zip(d.inputs, d.amplitude, d.phase_deg)]
        lines.append(f"worst other out-of-plane mode: {d.worst_other_db():.1f} dB re the target")
        lines += d.inseparable
        lines += self.set_lines()
        lines.append("timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in self.timings.items()))
        return lines

    def write(self, folder: str | Path | Claim,
              progress: Callable[[str], None] | None = None) -> Path:
        """Write ``drive.csv``, ``selectivity.csv``, ``response_set.txt`` (the ``--set``
        lines), ``excite_spectra.png`` and ``study.resolved.yaml`` into ``folder``."""
        from copdea_fem.folders import result_directory
        from copdea_fem.forced_response.excitation import DRIVE_COLUMNS, SELECTIVITY_COLUMNS
        from copdea_fem.reduced.io import write_csv
        from copdea_fem.study import dump_resolved

        d = self.design
        with claimed(folder, "excite", input_files(self.study)) as target:
            with reporting_to(progress):
                logger.info("writing results ...")
            with result_directory(target, "excite") as staging:
                write_csv(staging / "drive.csv", DRIVE_COLUMNS,
                          (d.inputs, d.amplitude, d.phase_deg))
                write_csv(staging / "selectivity.csv", SELECTIVITY_COLUMNS,
                          (d.labels, d.freq_hz, d.level_db))
                (staging / "response_set.txt").write_text("\n".join(self.set_lines()) + "\n")
                self._plot(staging / "excite_spectra.png")
                dump_resolved(self.study, staging / "study.resolved.yaml")
        return target

    def _plot(self, path: Path) -> None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        frequency, single, designed = self.spectra()
        figure, axes = plt.subplots(figsize=(7, 4))
        axes.semilogy(frequency, single, label="one electrode (inputs in phase)")
        axes.semilogy(frequency, designed, label="designed drive: " + ", ".join(
            self.design.targets))
        axes.set_xlabel("frequency [Hz]")
        axes.set_ylabel("mean |v| at the points [m/s]")
        axes.legend()
        figure.tight_layout()
        figure.savefig(path, dpi=110)
        plt.close(figure)


def statespace(study: Study | str | Path, *, allow_large: bool = False,
               progress: Callable[[str], None] | None = None,
               out: str | Path | Claim | Output | None = None) -> StateSpace:
    """The coupled modal model as a real LTI system ``x' = A x + B u, y = C x + D u``
    (``copdea-fem statespace``; :mod:`copdea_fem.forced_response.statespace`).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file (``load.voltage`` > 0; the damping the
        paper's modal b/m, ``reduced.damping_*``).
    allow_large, progress, out
        As :func:`solve`'s.

    Returns
    -------
    StateSpace
        ``system``: a ``control.StateSpace`` when python-control is installed, else the
        :class:`~copdea_fem.forced_response.statespace.StateSpaceModel` (the arrays).

    Raises
    ------
    StudyError
        A bad study, ``load.voltage = 0``, a membrane loss factor, Rayleigh or Prony damping.
    SolveFailed, PrestressError, OutputFolderError
        As :func:`solve`.
    """
    from copdea_fem.forced_response.statespace import (
        check_statespace_study,
        realise,
        statespace_microphones,
    )

    study = as_study(study)
    check_statespace_study(study)
    microphones = statespace_microphones(study)
    timings: dict = {}
    with claiming(out, "statespace", input_files(study), study.output.directory) as folder:
        with reporting_to(progress):
            _, model = _modal_model(study, allow_large, timings, microphones)
            start = time.perf_counter()
            system = realise(model)
            timings["realisation"] = time.perf_counter() - start
            logger.info(f"state space: {system.A.shape[0]} states, {len(system.inputs)} "
                        f"input(s), {len(system.outputs)} outputs")
        result = StateSpace(study, system, timings)
        if folder is not None:
            result.write(folder, progress)
    return result


class StateSpace:
    """The result of :func:`statespace`: the arrays, ``system``, ``write``."""

    def __init__(self, study: Study, model: StateSpaceModel, timings: dict) -> None:
        self.study, self.model, self.timings = study, model, timings

    @property
    def system(self):
        """A ``control.StateSpace`` (python-control installed), else the arrays
        (:class:`~copdea_fem.forced_response.statespace.StateSpaceModel`)."""
        converted = self.model.as_control()
        return self.model if converted is None else converted

    def summary_lines(self) -> list[str]:
        m = self.model
        microphones = sum(name.startswith("p_") for name in m.outputs)
        sound = f", pressure at {microphones} microphone(s)" if microphones else ""
        return [f"{self.study.name}: state space, {m.A.shape[0]} states, {len(m.inputs)} "
                f"input(s), {len(m.outputs)} outputs (velocity at "
                f"{(len(m.outputs) - len(m.inputs) - microphones) // 3} points{sound}, "
                "motional currents)",
                "timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in self.timings.items())]

    def write(self, folder: str | Path | Claim,
              progress: Callable[[str], None] | None = None) -> Path:
        """Write ``statespace.npz``, ``statespace.mat`` (scipy.io.savemat) and
        ``study.resolved.yaml`` into ``folder``."""
        import numpy as np
        import scipy.io

        from copdea_fem.folders import result_directory
        from copdea_fem.study import dump_resolved

        arrays = self.model.arrays()
        with claimed(folder, "statespace", input_files(self.study)) as target:
            with reporting_to(progress):
                logger.info("writing results ...")
            with result_directory(target, "statespace") as staging:
                np.savez(staging / "statespace.npz", **arrays)
                scipy.io.savemat(staging / "statespace.mat", arrays)
                dump_resolved(self.study, staging / "study.resolved.yaml")
        return target


__all__ = ["Excitation", "StateSpace", "excite", "statespace"]
