"""The public fit: logs or files in, a :class:`~frictid.result.FitResult` out (``frictid.fit``, ``frictid fit``).

Layer 3: this module reads the files (:func:`frictid.io.logs.read_logs`), plans the reading of Parquet
files joint by joint, hashes them, groups the logs by joint, and fits the joints one after another or in
worker processes (:mod:`frictid.parallel`). Each joint runs :func:`fit_joint`, the per-joint pipeline on
arrays: identify's steps (:mod:`frictid.identify.pipeline` lists them: prepare, rigid body, static maps,
choose, dynamics, thermal), then the diagnosis and its check (:mod:`frictid.diagnose`), then the last
step. ``identify`` and ``diagnose`` never read files; ``diagnose`` imports from ``identify``, never back.
"""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from typing import Callable

import numpy as np

from frictid import segments as seg
from frictid.data import JointLog
from frictid.diagnose import check_diagnosis, diagnose_fit
from frictid.errors import FrictidInputError, LogFormatError, combined_log_error
from frictid.identify import dynamics, maps, mechanics, prepare, thermal_fit, validity
from frictid.identify.pipeline import finish, nothing_identifiable, parse_models, thermal_names
from frictid.result import FitResult, JointFit
from frictid.io.logs import file_sha256, joint_row_blocks, read_logs
from frictid.parallel import Prefetch, map_ordered, n_workers

__all__ = ["fit", "fit_joint", "parse_models"]

#: Numerical failures inside a fit step (LAPACK not converging, a floating-point trap): the step's models
#: become not identifiable with the reason, never an internal error.
NUMERICAL_FAILURES = (np.linalg.LinAlgError, FloatingPointError, OverflowError, ZeroDivisionError)

#: Log channels the fit never reads (the references of the drive's controller): not read from files.
UNUSED_CHANNELS = ("q_ref", "qd_ref", "tau_ref")


@dataclass
class _Sourced:
    """A log read or given here, with the index of its source in the fit's ``sources`` (the caller's
    :class:`~frictid.data.JointLog` is not changed)."""

    log: JointLog
    source: int

    @property
    def joint(self):
        return self.log.joint


@dataclass
class _Block:
    """One joint's rows of a Parquet file (:func:`frictid.io.logs.joint_row_blocks`), read by the process
    that fits the joint: ``source`` indexes the fit's sources, ``rows`` is the block's size."""

    joint: str
    source: int
    rows: int
    load: Callable[[], list[JointLog]]


def preload() -> None:
    """Import what fitting a joint needs beyond the modules imported here (scipy.signal for the
    derivatives, 1.2 s in each of two workers at once against 0.75 s here), once, ahead of forking the
    workers that inherit it; in a background thread while the files are read (:class:`Prefetch`)."""
    import scipy.signal  # noqa: F401


def _load(paths_or_logs, mapping, units) -> tuple[list[_Sourced | _Block], list[dict]]:
    """The logs to fit and the sources they come from. A Parquet file whose joints are contiguous blocks
    of rows gives one :class:`_Block` per joint, read when the joint is fitted (in its worker: the
    reading is shared out, and no process holds every joint's samples); other files are read here.
    The files' SHA-256 and :func:`preload` run in background threads meanwhile."""
    if isinstance(paths_or_logs, (str, os.PathLike, JointLog)):
        paths_or_logs = [paths_or_logs]
    prefetch = Prefetch([str(p) for p in paths_or_logs if not isinstance(p, JointLog)], file_sha256, preload)
    try:
        logs, sources, files = _read_or_plan(paths_or_logs, mapping, units)
    finally:
        hashes = prefetch.hashes()
    for k in files:
        sources[k]["sha256"] = hashes.get(sources[k]["path"])
    return logs, sources


def _read_file(path: str, mapping, units, sources: list[dict]) -> list[_Sourced | _Block]:
    """A file's logs (or its joints' row blocks), its entry appended to ``sources`` (sha256 None)."""
    k = len(sources)
    blocks = joint_row_blocks(path, mapping, units) if path != "-" else None
    if blocks is not None:
        sources.append({"path": path, "sha256": None, "rows": int(sum(b - a for _, a, b in blocks))})
        return [_Block(j, k, b - a, functools.partial(read_logs, path, mapping, units,
                                                      skip=UNUSED_CHANNELS, rows=(a, b)))
                for j, a, b in blocks]
    got = read_logs(path, mapping, units, skip=UNUSED_CHANNELS)
    sources.append({"path": path, "sha256": None, "rows": int(sum(g.n for g in got))})
    return [_Sourced(g, k) for g in got]


def _read_or_plan(paths_or_logs, mapping, units) -> tuple[list[_Sourced | _Block], list[dict], list[int]]:
    """:func:`_load` without the hashes (``sha256`` None), and the indices of the sources that are files."""
    logs: list[_Sourced | _Block] = []
    sources: list[dict] = []
    files: list[int] = []
    errors: list[str] = []
    for item in paths_or_logs:
        if isinstance(item, JointLog):
            logs.append(_Sourced(item, len(sources)))
            sources.append({"path": item.source or "<memory>", "sha256": None, "rows": item.n})
            continue
        try:
            got = _read_file(str(item), mapping, units, sources)
        except LogFormatError as exc:
            errors.append(str(exc))
            continue
        files.append(len(sources) - 1)
        logs.extend(got)
    if errors:
        raise LogFormatError("", errors)
    if not logs:
        raise FrictidInputError("fit: no logs given")
    return logs, sources, files


def _fit_given(given: list[_Sourced | _Block], fit_one: Callable[[list[_Sourced]], JointFit]
               ) -> tuple[JointFit | None, list[tuple[int, int]], list[tuple[str, list[str]]]]:
    """Read a joint's :class:`_Block` items, then fit it: (the fit, rows dropped per source while reading,
    the problems of the blocks as (file, problems), the fit None then)."""
    jlogs: list[_Sourced] = []
    dropped: list[tuple[int, int]] = []
    problems: list[tuple[str, list[str]]] = []
    for item in given:
        if not isinstance(item, _Block):
            jlogs.append(item)
            continue
        try:
            got = item.load()
        except LogFormatError as exc:
            problems.append((exc.path, exc.problems))
            continue
        dropped.append((item.source, item.rows - sum(g.n for g in got)))
        jlogs.extend(_Sourced(g, item.source) for g in got)
    if problems:
        return None, dropped, problems
    return fit_one(jlogs), dropped, problems


def _by_joint(logs: list[_Sourced | _Block], joint) -> dict[str, list[_Sourced | _Block]]:
    """The logs grouped by joint (only ``joint`` when given)."""
    by_joint: dict[str, list[_Sourced | _Block]] = {}
    for lg in logs:
        by_joint.setdefault(str(lg.joint), []).append(lg)
    if joint is not None:
        if str(joint) not in by_joint:
            raise FrictidInputError(f"--joint {joint}: not in the logs; joints found: {', '.join(by_joint)}")
        by_joint = {str(joint): by_joint[str(joint)]}
    return by_joint


def fit(paths_or_logs, joint: str | None = None, models=None, mapping=None, units=None, *,
        n_folds: int = 5, segmenter: Callable | None = None, differentiate: Callable | None = None,
        diagnose: bool = True, jobs: int = 1) -> FitResult:
    """Identify friction models for every joint (or one) of one or more logs.

    paths_or_logs : a path, a :class:`~frictid.data.JointLog`, or a list of either (several logs of the
    same joint are fitted together). joint : only this joint. models : names or a comma list (default
    all of :data:`frictid.identify.pipeline.ALL_MODELS`). mapping, units : as ``--map`` / ``--units`` of
    :func:`frictid.io.logs.read_logs`. n_folds : folds of the held-out split. segmenter(log) -> segments and
    differentiate(log) -> (w, a) default to :func:`frictid.segments.find_segments` and
    :func:`frictid.segments.derivatives`.
    diagnose : run :func:`frictid.diagnose.diagnose_joint` on every joint (extensions beyond the base
    model enter only through its findings; ``selected`` then names the end of its chain).
    jobs : joints fitted at once in worker processes (forked: they share the logs read here); 0 means
    one per available core, 1 (the default) fits them one after another in this process. The result does
    not depend on it.

    Returns a :class:`~frictid.result.FitResult`; :func:`frictid.io.params.write_params` writes the parameter file.
    """
    wanted = parse_models(models)
    logs, sources = _load(paths_or_logs, mapping, units)
    by_joint = _by_joint(logs, joint)
    segmenter = segmenter or seg.find_segments
    differentiate = differentiate or seg.derivatives
    res = FitResult(sources=sources, settings={"models": wanted, "n_folds": n_folds,
                                                "heldout": "segment folds (plateaus sorted by velocity, "
                                                           "rank mod n_folds); duty cycles by cycle"})
    del logs  # by_joint holds them; a joint's logs are freed once it is fitted (serial path)
    names = list(by_joint)
    workers = n_workers(jobs, len(names))

    def one(j):
        return _fit_given(by_joint.pop(j) if workers <= 1 else by_joint[j],
                          lambda items: fit_joint([s.log for s in items], wanted, n_folds, segmenter,
                                                  differentiate, diagnose=diagnose,
                                                  sources=[s.source for s in items]))

    if workers > 1 and len(names) > 1:
        compile_kernels()
    done = map_ordered(one, names, workers)  # in this process when workers <= 1
    bad = combined_log_error(p for _, _, probs in done for p in probs)  # every joint's, together
    if bad is not None:
        raise bad
    for _, dropped, _ in done:
        for k, n in dropped:
            sources[k]["rows"] -= n
    res.joints.update((j, jf) for j, (jf, _, _) in zip(names, done))
    res.settings["diagnose"] = bool(diagnose)
    return res


def compile_kernels() -> None:
    """Compile the kernels every joint's fit calls, each for its one signature, in this process (or load them
    from numba's cache): the worker processes forked after it inherit them. Otherwise, on the first run after
    installing, every worker compiled its own copy of each (the same tens of seconds of CPU, once per worker);
    with the cache warm each loaded its own copy. A kernel called with other types still compiles where it is
    called."""
    from frictid.diagnose import samples
    from frictid.identify import varpro
    from frictid.models import replay_kernel
    from frictid.segments import duty, runs

    for kernel, signature in (*runs.KERNELS, *duty.KERNELS, *varpro.KERNELS, *replay_kernel.KERNELS,
                              *samples.KERNELS):
        kernel.compile(signature)


def fit_joint(jlogs: list[JointLog], wanted: list[str], n_folds: int, segmenter: Callable,
              differentiate: Callable, diagnose: bool = False, sources: list[int] | None = None) -> JointFit:
    """Identify everything for one joint from its logs: prepare, rigid body, static maps, choose, dynamics
    (LuGre), thermal, then the diagnosis and its check, and the last step (:func:`frictid.identify.pipeline.finish`).
    ``sources[i]``: the index of log i's source in the fit's ``sources`` (0 for every log by default)."""
    jd = prepare.prepare(jlogs, sources or [0] * len(jlogs), segmenter, differentiate)
    regs = mechanics.regressors(jd)
    poor = prepare.unidentifiable(jd.preps)
    if poor is not None:  # nothing in these logs can pin a friction number down: say so, fit nothing
        nothing_identifiable(jd, regs, wanted, poor)
        return jd.jf
    try:
        rb, fr = mechanics.rigid_body(jd, regs, n_folds)
        maps.static_maps(jd, rb, fr, wanted, n_folds)
        maps.choose_base(jd, fr, n_folds)
    except NUMERICAL_FAILURES as exc:  # a failure of the numerics is a verdict on the data, not a crash
        jd.jf.models.clear()
        nothing_identifiable(jd, regs, wanted, f"the least-squares fit failed numerically ({exc})")
        return jd.jf
    jd.jf.validity = validity.of_joint(jd.preps, fr, jd.min_speed)
    if "lugre" in wanted:
        _optional_step(jd, ["lugre"], dynamics.fit_lugre, jd, jd.jf.selected)
    th_wanted = thermal_names(wanted)
    if th_wanted:
        _optional_step(jd, th_wanted, thermal_fit.fit_thermal_models, jd, th_wanted)
    # the diagnosis: every extension beyond the base model enters through a finding (frictid.diagnose)
    if diagnose and jd.jf.selected is not None:
        choice = jd.jf.selected
        diagnose_fit(jd.jf, jd.preps)
        check_diagnosis(jd.jf, jd.preps, choice, fr.basis, jd.min_speed, fr.excl)
    finish(jd)
    return jd.jf


def _optional_step(jd, names: list[str], step: Callable, *args) -> None:
    """Run a step that adds the models ``names`` (LuGre, thermal); when its numerics fail, those models are
    dropped and listed as not identified with the reason."""
    try:
        step(*args)
    except NUMERICAL_FAILURES as exc:
        for m in names:
            jd.jf.models.pop(m, None)
            jd.jf.not_identified.append({"what": m, "reason": f"the fit failed numerically ({exc})"})
