"""Parameter sweeps (paper Fig. 11): a base study, a grid over study keys, tracked modes.

``copdea-fem sweep SWEEP.yaml [--out DIR]`` runs every grid point with the
dry FE, the reduced (ring) model or the fully-coupled FE (air + PML),
follows every mode from point to point (:mod:`copdea_fem.sweeps.tracking`) and
writes one long table plus Fig. 11-style plots.

SWEEP.yaml
----------
::

    name: fig11b_g1_z                   # optional (default: file name)
    description: "..."                  # optional
    study: ../g1_z16_v2.yaml            # base study, relative to this file
    set:                                # optional overrides of the base study
      load.voltage: 2 kV
    model: dry                          # dry | reduced | coupled
    axes:                               # one or several study keys; grid = product
      load.z: 0..18 mm, 10 points       # or "0 mm..18 mm, step 2 mm", a list
                                        # [0 mm, 6 mm, 12 mm] or {start, stop, points|step}
    tracking: {mac_min: 0.3, label_weight: 0.25, frequency_weight: 0.5, pair_tolerance: 0.01}
    execution:                          # optional; CLI options override
      executor: inline                  # inline | processes | dask
      workers: 2                        # worker processes of processes
      scheduler: null                   # dask scheduler address; null: a local cluster
      chain_length: auto                # points per continuation chain (auto or >= 1)
      reuse: true                       # or false, or {mesh, prestress, shifts}
    output:
      directory: results/sweeps/<name>
      plots: true
      plot_kinds: [out-of-plane, pumping]

Every point's study is validated before anything is solved; errors are
:class:`SweepError` (a ``ValueError``) naming the key, the value and what is
allowed.

Reuse between neighbouring points (``model: dry``)
---------------------------------------------------
The grid is walked in *continuation order*: axes that change the mesh or the
material (anything outside ``load``, ``eigen``, ``disc``, ``spring``,
``reduced``, ``excitation``, ``effects``, ``output``) outermost, then a
serpentine (boustrophedon) over the rest, so consecutive points differ in one
axis by one step.  Consecutive points with the same *context* (mesh +
material + prestress settings) form a chain; inside a chain

* the mesh is built (or read from ``meshes/``) once per geometry and kept in
  memory (``reuse.mesh``);
* one :class:`copdea_fem.fe.prestress.MembraneSolver` continues from the
  neighbour's equilibrium in a single adaptive load step instead of the full
  z-then-V_b path from the flat state (``reuse.prestress``);
* the band eigensolver starts at the neighbour's shifts asking for as many
  modes as the neighbour found around each (``reuse.shifts``,
  ``solve_band(initial_shifts=...)``); the band is still certified, so a poor
  start costs time, never modes.

The factorisation's symbolic analysis is *not* reused: NGSolve's UMFPACK and
PARDISO wrappers and SciPy's SuperLU redo it inside every factorisation and
expose no numeric-only refactorisation.  Measured on the G1 operator (9054
unknowns, NGSolve's timers, one BLAS thread, one factorisation per point): the
symbolic analysis is a quarter of the numeric factorisation and a negligible share
of a continued point, so there is little to buy (the eigen stage's cost is
ARPACK's ~190 solves per point; docs/benchmarks.md).

Execution
---------
The executors are those of :mod:`copdea_fem.parallel` (the old ``local`` and ``pool``
still work, with a deprecation warning).
``inline`` runs the chains one after the other in this process; ``processes`` runs
chains in worker processes (spawned; each writes its points); ``dask`` sends
each point to an existing Dask cluster as a task that depends on its chain
predecessor and prefers the same worker, which keeps the chain's solver in a
worker-local cache (a worker that lacks it -- restarted, or another one --
solves from scratch: slower, same result).  All three gather into the same
table because tracking runs afterwards, on the stored results, along the
continuation path.

On disk (resumable)::

    OUT/points/<id>/result.json    one per point, written atomically
    OUT/points/<id>/vectors.npz    shapes for the MAC (ok points)
    OUT/sweep.csv                  the long table
    OUT/sweep.json                 per-point status, timings, reuse; track labels
    OUT/sweep.png                  frequency vs the swept parameter (Fig. 11 style)
    OUT/sweep.resolved.yaml        the sweep with every point's values, SI

A point whose ``result.json`` says ``ok`` for the same resolved study (hash)
is not recomputed; failed or stale points are.  A failing point is recorded
with its error and does not stop the sweep.

The package follows the pipeline of a sweep: :mod:`.spec` (the sweep file) and
:mod:`.axes` (its axes), :mod:`.grid` (points and their keys), :mod:`.models` (one point
through the dry, coupled or reduced model), :mod:`.store` (point folders),
:mod:`.executors` (inline, processes, dask: the worker processes and the Dask cluster
are :mod:`copdea_fem.parallel`'s, shared with the diagnosis's FE solves), :mod:`.gather`
(tracking, tables) with
:mod:`.tracking` (the mode tracking itself) and :mod:`.plots`.  The reuse benchmark is
``python -m benchmarks.sweep benchmark SWEEP.yaml`` (``benchmarks/sweep.py``, outside the
package).
"""

from copdea_fem.sweeps.executors import run_sweep
from copdea_fem.sweeps.gather import SweepOutcome, finish_sweep, format_summary, read_table
from copdea_fem.sweeps.models import MODEL_CLASSES, PointResult, shift_plan, solve_point
from copdea_fem.sweeps.plots import plot_sweep
from copdea_fem.sweeps.spec import (
    Axis,
    ExecutionSettings,
    ReuseSettings,
    Sweep,
    SweepError,
    SweepPoint,
    check_chain_length,
    load_sweep,
    parse_reuse,
    parse_sweep,
)
from copdea_fem.sweeps.store import PointStore

__all__ = ["Axis", "ExecutionSettings", "MODEL_CLASSES", "PointResult", "PointStore",
           "ReuseSettings", "Sweep", "SweepError", "SweepOutcome", "SweepPoint",
           "check_chain_length", "finish_sweep", "format_summary", "load_sweep", "parse_reuse",
           "parse_sweep", "plot_sweep", "read_table", "run_sweep", "shift_plan", "solve_point"]
