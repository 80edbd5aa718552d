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
    from copdea_fem.forced_response.state_space import StateSpaceModel

logger = logging.getLogger("copdea_fem")

#: Lines of the spectra plot of ``excite`` [per Hz of the band].
SPECTRUM_LINES = 2000


def _modal_model(study: Study, allow_large: bool, timings: dict, microphones=(),
                 radiating: bool = False):
    """The solve of ``study`` and its modal model for the study's inputs at its points (and
    ``microphones``: :func:`copdea_fem.forced_response.state_space.statespace_microphones`;
    ``radiating``: the radiating band as states, :meth:`.ModalInputs.build`)."""
    from copdea_fem.fe import engine_for, run_solve
    from copdea_fem.forced_response.modal_inputs import ModalInputs, drive_inputs, study_points

    engine = engine_for(study, forced_response=True)
    check_size(study, allow_large, engine)
    start = time.perf_counter()
    with solving(study):
        solution = run_solve(study, engine=engine)
    timings["solve"] = time.perf_counter() - start
    start = time.perf_counter()
    names, positions = study_points(solution, study)
    model = ModalInputs.build(solution, study, drive_inputs(study), positions, names,
                              microphones, radiating=radiating)
    timings["modal model"] = time.perf_counter() - start
    return solution, model


def excite(study: Study | str | Path, targets: Sequence[str], *, max_ac: float | None = None,
           hold_in_plane: bool = False, allow_large: bool = False, progress: Callable[[str], None] | None = None,
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
    hold_in_plane : bool
        Hold the in-plane modes down too (``--hold-in-plane``); by default they are
        watched: their levels reported in ``selectivity.csv`` and a loud one warned of.
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
    from copdea_fem.forced_response.state_space import check_statespace_study

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
            solution, model = _modal_model(study, allow_large, timings)
            start = time.perf_counter()
            design = design_drive(model, targets, amplitude, study.eigen.f_max,
                                  hold_in_plane)
            timings["design"] = time.perf_counter() - start
            for line in design.inseparable + design.loud_watched():
                logger.warning(line)
        result = Excitation(study, model, design, timings, solution)
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
    solution : copdea_fem.fe.SolveResult, optional
        The solve the model was built from (for :meth:`operating_shape`).
    """

    def __init__(self, study: Study, model: ModalInputs, design: ExcitationDesign,
                 timings: dict, solution=None) -> None:
        self.study, self.model, self.design, self.timings = study, model, design, timings
        self.solution = solution

    @property
    def drive(self) -> pd.DataFrame:
        """``drive.csv``: ``segment, amplitude, phase_deg`` [-, V, deg]."""
        import pandas as pd

        from copdea_fem.forced_response.excitation import DRIVE_COLUMNS
        d = self.design
        return pd.DataFrame(dict(zip(DRIVE_COLUMNS, (d.inputs, d.amplitude, d.phase_deg))))

    @property
    def selectivity(self) -> pd.DataFrame:
        """``selectivity.csv``: ``label, freq_hz, level_db, kind`` [-, Hz, dB re the target,
        ``out-of-plane``/``in-plane``]: the criterion's modes, then the watched in-plane
        ones."""
        import pandas as pd

        from copdea_fem.forced_response.excitation import SELECTIVITY_COLUMNS
        return pd.DataFrame(dict(zip(SELECTIVITY_COLUMNS, self.design.rows())))

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

    def operating_shape(self, target: str | None = None):
        """The designed drive's operating shape at ``target``'s frequency (default: the
        first target): a :class:`~copdea_fem.vtu.VtuMesh` of the prestressed membrane with
        the velocity [m/s] as point data, ``e^{+i omega t}`` convention
        (:mod:`copdea_fem.forced_response.operating_shape`: the fields and their units)."""
        import numpy as np

        from copdea_fem.fe.forced.electrode import segment_weights
        from copdea_fem.forced_response.operating_shape import operating_shape_mesh
        from copdea_fem.forced_response.run import modal_damping

        d = self.design
        target = d.targets[0] if target is None else target
        if target not in d.targets:
            raise StudyError(f"operating shape of {target!r}: not a target; allowed: "
                             + ", ".join(d.targets))
        if self.solution is None:
            raise StudyError("operating shape: this Excitation holds no solve; allowed: "
                             "the result of excite()")
        weights = {name: weight for name, weight, _ in segment_weights(self.study)}
        drive = [(weights[name], np.conj(u)) for name, u in zip(d.inputs, d.drive)]
        study = self.study

        def damping(mode):
            return float(modal_damping([mode.label], [mode.kind], study)[0])

        return operating_shape_mesh(self.solution, study, drive,
                                    d.freq_hz[d.labels.index(target)], damping)

    def summary_lines(self) -> list[str]:
        import numpy as np
        d = self.design
        lines = [f"{self.study.name}: drive of {len(d.inputs)} input(s) for "
                 + ", ".join(d.targets) + f" (peak {np.abs(d.drive).max():g} V)"]
        lines += [f"{name:>12} {amplitude:9.3f} V {phase:8.2f} deg"
                  for name, amplitude, phase in zip(d.inputs, d.amplitude, d.phase_deg)]
        held = "mode" if any(kind != "out-of-plane" for kind in d.kinds) else "out-of-plane mode"
        lines.append(f"worst other {held}: {d.worst_other_db():.1f} dB re the target")
        lines += d.inseparable + d.loud_watched()
        lines += self.set_lines()
        lines.append("timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in self.timings.items()))
        return lines

    def write(self, folder: str | Path | Claim,
              progress: Callable[[str], None] | None = None) -> Path:
        """Write ``drive.csv``, ``selectivity.csv``, ``response_set.txt`` (the ``--set``
        lines), ``excite_spectra.png`` (``output.plots``), ``operating_shape_<target>.vtu``
        per target with ``operating_shape.pvd`` (``output.paraview``; :meth:`operating_shape`)
        and ``study.resolved.yaml`` into ``folder``."""
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
                write_csv(staging / "selectivity.csv", SELECTIVITY_COLUMNS, d.rows())
                (staging / "response_set.txt").write_text("\n".join(self.set_lines()) + "\n")
                if self.study.output.plots:
                    self._plot(staging / "excite_spectra.png")
                if self.study.output.paraview and self.solution is not None:
                    self._paraview(staging)
                dump_resolved(self.study, staging / "study.resolved.yaml")
        return target

    def _paraview(self, staging: Path) -> None:
        from copdea_fem.vtu import safe_name, write_pvd, write_vtu

        d = self.design
        files = []
        start = time.perf_counter()
        for target in d.targets:
            files.append(staging / f"operating_shape_{safe_name(target)}.vtu")
            write_vtu(files[-1], self.operating_shape(target))
        self.timings["operating shape"] = time.perf_counter() - start
        write_pvd(staging / "operating_shape.pvd", files,
                  [d.freq_hz[d.labels.index(target)] for target in d.targets])

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
    (``copdea-fem statespace``; :mod:`copdea_fem.forced_response.state_space`).

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
        :class:`~copdea_fem.forced_response.state_space.StateSpaceModel` (the arrays).

    Raises
    ------
    StudyError
        A bad study, ``load.voltage = 0``, a membrane loss factor, Rayleigh or Prony damping.
    SolveFailed, PrestressError, OutputFolderError
        As :func:`solve`.
    """
    from copdea_fem.forced_response.state_space import (
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
            _, model = _modal_model(study, allow_large, timings, microphones, radiating=True)
            start = time.perf_counter()
            system = realise(model)
            timings["realisation"] = time.perf_counter() - start
            system.units["band"] = (
                f"the modes up to eigen.f_max = {study.eigen.f_max:g} Hz as states, those "
                "above as one pseudo-mode per input and part; measured on the quick G1 "
                "against the FE: 0.5 % up to f_max / 2 with f_max = 2 kHz, 4 % below f_max / 2 "
                "and up to a third near f_max with f_max = 1 kHz (docs/excitation.md, "
                "Accuracy)")
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
        (:class:`~copdea_fem.forced_response.state_space.StateSpaceModel`)."""
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
