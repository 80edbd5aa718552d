"""A scan written as a PSV-like UFF export (:func:`write_scan`; read back by
:func:`copdea_fem.measured.read_scan`)."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from copdea_fem.measured.scan import ScanData
from copdea_fem.measured.uff_units import RESPONSE_CODES


def write_scan(path, scan: ScanData, *, binary: bool = True) -> Path:
    """A :class:`ScanData` as a PSV-like UFF export: 164 (SI), 2411 (the points, model
    frame, m), one 58 (function type 4, velocity per volt) per channel.

    A channel along a global axis gets ``rsp_dir`` +-1..3; any other direction (a 1-D
    laser) gets ``rsp_dir`` 0 and must be given to :func:`copdea_fem.measured.read_scan`
    again.  Abscissae are written with 6 significant digits (pyuff's ``%13.5e``), values as
    doubles (binary) or with 12 significant digits (ASCII, pyuff's ``%20.11e``).
    """
    import pyuff

    path = Path(path)
    if scan.quantity != "frf":
        raise ValueError(f"write_scan: quantity = {scan.quantity!r} is not allowed; "
                         "allowed: 'frf' (UFF function type 4)")
    ordinate_unit = {"displacement": "m", "velocity": "m/s",
                     "acceleration": "m/s^2"}.get(scan.response, "NONE")
    code = {v: k for k, v in RESPONSE_CODES.items()}.get(scan.response, 0)
    sets = [pyuff.prepare_164(units_code=1, units_description="SI", temp_mode=1, length=1.0,
                              force=1.0, temp=1.0, temp_offset=273.15),
            pyuff.prepare_2411(node_nums=np.asarray(scan.nodes, int),
                               def_cs=np.zeros(scan.n_points, int),
                               disp_cs=np.zeros(scan.n_points, int),
                               color=np.full(scan.n_points, 8, int),
                               x=scan.positions[:, 0], y=scan.positions[:, 1],
                               z=scan.positions[:, 2])]
    frequencies = np.asarray(scan.frequencies, float)
    for channel in range(scan.n_channels):
        direction = np.asarray(scan.channel_direction[channel], float)
        axis = int(np.argmax(np.abs(direction)))
        along_axis = abs(abs(direction[axis]) - 1.0) < 1e-9
        rsp_dir = int(np.sign(direction[axis]) * (axis + 1)) if along_axis else 0
        record = pyuff.prepare_58(
            binary=int(bool(binary)), id1=f"{scan.response} / voltage", id2="copdea-fem",
            id4=f"channel {channel + 1}", func_type=4, rsp_ent_name="SCAN",
            rsp_node=int(scan.nodes[scan.channel_point[channel]]), rsp_dir=rsp_dir,
            ref_ent_name="DRIVE", ref_node=0, ref_dir=0, ord_data_type=6,
            num_pts=frequencies.size, abscissa_spacing=1, abscissa_min=float(frequencies[0]),
            abscissa_inc=float(frequencies[1] - frequencies[0]), abscissa_spec_data_type=18,
            abscissa_axis_units_lab="Hz", ordinate_spec_data_type=code,
            ordinate_axis_units_lab=ordinate_unit, orddenom_spec_data_type=0,
            orddenom_axis_units_lab="V", data=np.asarray(scan.values[channel], complex),
            x=frequencies)
        record.update(abscissa_axis_lab="Frequency", ordinate_axis_lab=scan.response.capitalize(),
                      orddenom_axis_lab="Voltage")
        sets.append(record)
    uniform = np.allclose(np.diff(frequencies), frequencies[1] - frequencies[0], rtol=1e-9)
    if not uniform:
        for record in sets[2:]:
            record["abscissa_spacing"] = 0
    path.unlink(missing_ok=True)
    with contextlib.redirect_stdout(io.StringIO()):
        pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return path


__all__ = ["write_scan"]
