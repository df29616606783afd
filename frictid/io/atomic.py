"""Atomic output: write to a temporary file in the target's folder, then rename over the target.

An interrupted or failed run leaves any previous output untouched and no partial file under the target's
name. Standard output (``-``) is written directly.
"""
from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
from pathlib import Path
from typing import IO, Iterator

from ..errors import FrictidInputError


#: Set when the process was asked to stop (SIGTERM): no output is renamed into place after it, even if
#: the SystemExit raised by the handler was swallowed by a library on its way up.
STOP_REQUESTED = threading.Event()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def is_stdio(path) -> bool:
    return str(path) == "-"


def _input_files(inputs, mapping=None) -> list[Path]:
    """Every file a run reads: the inputs, their metadata sidecars (``<log>.meta.yaml``) and a mapping
    file given as ``--map FILE``."""
    out = []
    for src in [*inputs, *([mapping] if mapping else [])]:
        if src is None or is_stdio(src):
            continue
        p = Path(src)
        for cand in (p, Path(f"{p}.meta.yaml")):
            if cand.is_file():
                out.append(cand)
    return out


def check_output_path(path, inputs=(), mapping=None, sidecar: bool = False) -> None:
    """Refuse an output path that is an input (or an input's sidecar, or the ``--map`` file), or whose
    folder does not exist, before any work is done. ``sidecar``: the output also writes
    ``<path>.meta.yaml`` (CSV logs and tables), which must not be an input either."""
    if is_stdio(path):
        return
    p = Path(path)
    if p.is_dir():
        raise FrictidInputError(f"{p}: is a folder; give a file name for the output")
    if not p.parent.exists():
        raise FrictidInputError(f"{p}: folder {p.parent} does not exist; create it first")
    targets = [p] + ([Path(f"{p}.meta.yaml")] if sidecar else [])
    for src in _input_files(inputs, mapping):
        for target in targets:
            try:
                same = target.exists() and os.path.samefile(target, src)
            except OSError:
                same = False
            if same:
                raise FrictidInputError(
                    f"{target}: is also an input ({src}); frictid never overwrites an input, "
                    "choose another output name")


@contextlib.contextmanager
def atomic_path(path) -> Iterator[str]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``, on failure delete it."""
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=str(p.parent or "."))
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual permissions
    try:
        yield tmp
        if STOP_REQUESTED.is_set():
            raise SystemExit(143)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_open(path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open ``path`` for writing atomically; ``-`` gives standard output (text or binary)."""
    if is_stdio(path):
        stream = sys.stdout.buffer if "b" in mode else sys.stdout
        yield stream
        stream.flush()
        return
    with atomic_path(path) as tmp:
        kwargs = {} if "b" in mode else {"encoding": encoding, "newline": ""}
        with open(tmp, mode, **kwargs) as fh:
            yield fh
