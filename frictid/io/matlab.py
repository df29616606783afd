"""MATLAB ``.mat`` logs: named variables and struct fields mapped onto the joint-log columns.

A mapping file says where each column lives, with dotted paths into structs::

    variables: {t: rec.time_cont, q: rec.act_pos_mot_deg, tau: rec.act_torque_abs_nm}
    scale: {tau: para.u}          # a number, a list (one per joint) or the path of a variable in the file
    units: {q: deg}
    joints: [A1, A2, A3, A4, A5, A6]   # names for the rows of 2-D arrays (optional)

A 1-D variable is one joint; a 2-D variable holds one joint per row (or column: the axis whose length
matches ``t`` is the time axis). The result is the long-format table the CSV and Parquet readers give.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from ..errors import ConfigError, LogFormatError


def _lookup(data: dict, path: str, label: str):
    node = data
    for i, part in enumerate(path.split(".")):
        if isinstance(node, dict):
            if part not in node:
                have = ", ".join(k for k in node if not k.startswith("__"))
                raise LogFormatError(label, [f"variable {'.'.join(path.split('.')[:i + 1])!r} not found; "
                                             f"the file has: {have}"])
            node = node[part]
        else:
            fields = getattr(node, "_fieldnames", None)
            if fields is None or part not in fields:
                raise LogFormatError(label, [f"{path!r}: {'.'.join(path.split('.')[:i])!r} has no field "
                                             f"{part!r}; fields: {', '.join(fields or [])}"])
            node = getattr(node, part)
    return node


def _scale_value(spec_value, data, label, n_joints):
    if isinstance(spec_value, str):
        v = np.asarray(_lookup(data, spec_value, label), dtype=float).ravel()
    else:
        v = np.asarray(spec_value, dtype=float).ravel()
    if v.size == 1:
        return np.full(n_joints, float(v[0]))
    if v.size < n_joints:
        raise ConfigError(f"{label}: scale has {v.size} values for {n_joints} joints")
    return v[:n_joints]


def read_mat(path: str, variables: dict, scale: dict, joints: list | None) -> pa.Table:
    """Read the mapped variables of a .mat file as a long-format table (columns named as targets)."""
    import scipy.io

    if not variables:
        raise ConfigError(f"{path}: a .mat log needs a mapping file with `variables:` "
                          "(e.g. variables: {t: t, q: qm, tau: vir}); see docs/log-format.md")
    try:
        data = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
    except (ValueError, OSError, NotImplementedError, TypeError) as exc:
        raise LogFormatError(path, [f"cannot be read as a MATLAB file ({exc}); MATLAB v7.3 (HDF5) files "
                                    "need saving as -v7 first"]) from None
    if "t" not in variables:
        raise ConfigError(f"{path}: variables: needs t (the time variable)")
    t = np.asarray(_lookup(data, variables["t"], path), dtype=float).ravel()
    n = t.size
    cols: dict[str, np.ndarray] = {}
    n_joints = 1
    for target, src in variables.items():
        if target == "t":
            continue
        a = np.asarray(_lookup(data, str(src), path), dtype=float)
        a = np.atleast_1d(np.squeeze(a))
        if a.ndim == 1:
            if a.size != n:
                raise LogFormatError(path, [f"variable {src!r} has {a.size} samples, t has {n}"])
            a = a[None, :]
        elif a.ndim == 2:
            if a.shape[1] != n and a.shape[0] == n:
                a = a.T
            if a.shape[1] != n:
                raise LogFormatError(path, [f"variable {src!r} has shape {a.shape}; neither axis matches "
                                            f"the {n} samples of t"])
        else:
            raise LogFormatError(path, [f"variable {src!r} has {a.ndim} dimensions; expected 1 or 2"])
        cols[target] = a
        n_joints = max(n_joints, a.shape[0])
    scales = {target: _scale_value(scale[target], data, path, n_joints) for target in cols if target in scale}
    return long_table(t, cols, scales, joints, path)


def long_table(t: np.ndarray, cols: dict[str, np.ndarray], scales: dict[str, np.ndarray],
               joints: list | None, label: str) -> pa.Table:
    """Long-format table from per-joint rows: each value of ``cols`` has shape (1 or n_joints, len(t))."""
    n = t.size
    n_joints = max((a.shape[0] for a in cols.values()), default=1)
    names = [str(j) for j in joints] if joints else [str(i + 1) for i in range(n_joints)]
    if len(names) < n_joints:
        raise ConfigError(f"{label}: joints: {len(names)} names for {n_joints} joints")
    names = names[:n_joints]
    out = {"t": np.tile(t, n_joints), "joint": np.repeat(np.array(names, dtype=object), n)}
    for target, a in cols.items():
        if a.shape[0] == 1 and n_joints > 1:
            a = np.repeat(a, n_joints, axis=0)
        if target in scales:
            a = a * scales[target][:n_joints, None]
        out[target] = a.reshape(-1)
    if n_joints == 1:
        del out["joint"]
    return pa.table({k: pa.array(v) for k, v in out.items()})


def read_signal_files(folder: str, files: dict, scale: dict, joints: list | None) -> pa.Table:
    """One plain-text file per signal (numbers separated by whitespace or newlines), several joints
    interleaved sample by sample (``q1 q2 ... qn`` of the first sample, then the second, ...)."""
    from pathlib import Path

    base = Path(folder)
    if "t" not in files:
        raise ConfigError(f"{folder}: files: needs t (the time file)")

    def load(target):
        p = base / files[target]
        if not p.is_file():
            raise LogFormatError(str(p), [f"file for column {target!r} not found (files: in the mapping)"])
        try:
            return np.loadtxt(p, dtype=float).ravel()
        except ValueError as exc:
            raise LogFormatError(str(p), [f"not plain numbers ({exc})"]) from None

    t = load("t")
    cols = {}
    for target in files:
        if target == "t":
            continue
        v = load(target)
        if v.size % t.size:
            raise LogFormatError(str(base / files[target]), [
                f"{v.size} values are not a whole number of joints for {t.size} time samples"])
        cols[target] = v.reshape(t.size, -1).T
    scales = {}
    for target, f in scale.items():
        if target in cols:
            v = np.atleast_1d(np.asarray(f, dtype=float))
            scales[target] = np.full(cols[target].shape[0], v[0]) if v.size == 1 else v
    return long_table(t, cols, scales, joints, folder)
