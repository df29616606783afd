"""Wide logs: one row per instant with each joint's signals side by side (a robot controller's record,
e.g. UR RTDE's ``actual_q_0 ... actual_q_5``), read through a mapping file that names every joint's
columns::

    map: {timestamp: t}                     # columns all joints share
    joints:
      base:     {map: {actual_q_0: q, actual_qd_0: qd, actual_current_0: tau}, scale: {tau: 10.0}}
      shoulder: {map: {actual_q_1: q, actual_qd_1: qd, actual_current_1: tau}, scale: {tau: 10.6956}}

The table is rearranged into one block of rows per joint (the shape frictid's reader splits), each block
holding the shared columns and the joint's own under their canonical names, its ``scale`` factors applied
(on top of a top-level ``scale``, which the reader applies afterwards).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..data import OPTIONAL_CHANNELS
from ..errors import LogFormatError


def wide_sources(spec) -> set[str]:
    """The source columns the joints of a wide mapping name (read besides the shared ones)."""
    return {src for m in spec.joint_maps.values() for src in m}


def _float(col, label: str, name: str) -> np.ndarray:
    if isinstance(col, np.ndarray):
        return col.astype(float, copy=False)
    try:
        return pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        raise LogFormatError(label, [f"column {name!r} is not numeric; a wide log's columns must be numbers"]) from None


def _without_absent_options(spec, names: list[str]):
    """``spec`` without an optional channel (``temp_joint``, ``q_ref`` ...) that no joint's columns hold: a
    mapping file can name a controller's optional signals once for recordings with and without them."""
    absent = {target for m in spec.joint_maps.values() for src, target in m.items()
              if target in OPTIONAL_CHANNELS and src not in names}
    absent = {t for t in absent if all(src not in names for m in spec.joint_maps.values()
                                       for src, tt in m.items() if tt == t)}
    if not absent:
        return spec
    maps = {j: {src: t for src, t in m.items() if t not in absent} for j, m in spec.joint_maps.items()}
    return replace(spec, joint_maps=maps)


def wide_to_long(table, label: str, spec) -> pa.Table:
    """``table`` (source column names) as one block of rows per joint of ``spec.joint_maps``, in the
    mapping's joint order, with a ``joint`` column. Every joint must map the same canonical columns."""
    names = list(table.column_names)
    spec = _without_absent_options(spec, names)
    missing = sorted({src for src in wide_sources(spec) if src not in names})
    if missing:
        raise LogFormatError(label, [f"the mapping names column(s) {', '.join(missing)}, which the log does "
                                     f"not have (columns: {', '.join(names[:12])}{' ...' if len(names) > 12 else ''})"])
    own = {src for src in wide_sources(spec)}
    shared = {spec.rename.get(c, c): c for c in names if c not in own}
    targets = {j: sorted(m.values()) for j, m in spec.joint_maps.items()}
    first = next(iter(targets.values()))
    odd = [j for j, t in targets.items() if t != first]
    if odd:
        raise LogFormatError(label, [f"joint {odd[0]} maps {', '.join(targets[odd[0]])} but joint "
                                     f"{next(iter(targets))} maps {', '.join(first)}; map the same signals for "
                                     "every joint"])
    clash = sorted(set(first) & set(shared))
    if clash:
        raise LogFormatError(label, [f"{', '.join(clash)} is both a shared column and a joint's own; map it "
                                     "in one place"])
    cols: dict[str, list[np.ndarray]] = {c: [] for c in [*shared, *first]}
    joints = list(spec.joint_maps)
    for j in joints:
        for target, src in shared.items():
            cols[target].append(_float(table.column(src), label, src))
        scale = spec.joint_scale.get(j, {})
        for src, target in spec.joint_maps[j].items():
            cols[target].append(_float(table.column(src), label, src) * float(scale.get(target, 1.0)))
    n = table.num_rows
    data = {c: pa.array(np.concatenate(parts)) for c, parts in cols.items()}
    data["joint"] = pa.DictionaryArray.from_arrays(np.repeat(np.arange(len(joints), dtype=np.int32), n),
                                                   pa.array(joints)).dictionary_decode()
    return pa.table(data)
