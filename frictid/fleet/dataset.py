"""The partitions of a dataset of logs and their content hashes.

A dataset is a hive-partitioned folder (``robot=r1/joint=j2/date=2026-03-01/part-0.parquet``, any key
names) or a list of log files. A partition is every log file below one combination of key values: one
robot-joint-run. Its content hash covers the bytes of its files and the fit options, so a re-run skips
exactly the partitions whose inputs did not change.
"""
from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import FrictidInputError

#: Log files a dataset folder may hold (sidecars ``*.meta.yaml`` belong to their CSV log).
LOG_SUFFIXES = (".parquet", ".csv")
#: Key names taken as the time axis of a trend, in this order; else the last key.
TIME_KEYS = ("date", "day", "run", "time")
_KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)=(.+)$")


@dataclass(frozen=True)
class Partition:
    """One robot-joint-run: its key values (in path order) and its log files (sorted)."""

    keys: tuple[tuple[str, str], ...]
    files: tuple[str, ...]

    @property
    def id(self) -> str:
        """``robot=r1/joint=j2/date=2026-03-01`` (for a list of files: ``file=<path>``)."""
        return "/".join(f"{k}={v}" for k, v in self.keys)

    def content_hash(self, salt: str = "") -> str:
        """BLAKE2b of the files' names and bytes (and their CSV sidecars) and ``salt`` (the fit options)."""
        h = hashlib.blake2b(digest_size=16)
        h.update(salt.encode())
        for f in self.files:
            for p in (Path(f), Path(f + ".meta.yaml")):
                if not p.exists():
                    continue
                h.update(p.name.encode() + b"\0")
                with open(p, "rb") as fh:
                    for block in iter(lambda: fh.read(1 << 20), b""):
                        h.update(block)
        return h.hexdigest()


def hive_keys(path: Path, root: Path) -> tuple[tuple[str, str], ...]:
    """The ``name=value`` folders between ``root`` and a file."""
    out = []
    for part in path.relative_to(root).parent.parts:
        m = _KEY.match(part)
        if m:
            out.append((m.group(1), m.group(2)))
    return tuple(out)


@dataclass(frozen=True)
class KeySpec:
    """Which dataset keys name a joint (``joint``, in order) and which one orders its runs (``time``):
    ``--keys robot,joint:date``."""

    joint: tuple[str, ...]
    time: str

    @property
    def names(self) -> tuple[str, ...]:
        return (*self.joint, self.time)

    def __str__(self) -> str:
        return f"{','.join(self.joint)}:{self.time}"


def parse_keys(text: str | None) -> KeySpec | None:
    """``"robot,joint:date"`` -> KeySpec (None for None). Raises FrictidInputError on a malformed text."""
    if text is None:
        return None
    hint = "give the keys that name a joint, then after a colon the key that orders its runs (--keys robot,joint:date)"
    joint, sep, time_ = text.partition(":")
    names = [k.strip() for k in joint.split(",") if k.strip()]
    bad = [k for k in [*names, time_.strip()] if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", k)]
    if not sep or not time_.strip() or bad:
        raise FrictidInputError(f"--keys {text!r}: " + (f"{bad[0]!r} is not a key name; " if bad and bad[0] else "")
                                + hint)
    if len(set(names)) < len(names) or time_.strip() in names:
        raise FrictidInputError(f"--keys {text!r}: a key is named twice; {hint}")
    return KeySpec(tuple(names), time_.strip())


def check_keys(spec: KeySpec | None, available, where: str) -> None:
    """Refuse keys the dataset or store does not have, naming those it has."""
    missing = [k for k in (spec.names if spec else ()) if k not in available]
    if missing:
        raise FrictidInputError(f"--keys {spec}: {where} has no key {missing[0]!r}; its keys are "
                                + (", ".join(available) or "none (no name=value folders)"))


def find_partitions(sources: list[str], spec: KeySpec | None = None) -> list[Partition]:
    """Partitions of a dataset: one folder (hive-partitioned) or a list of files (one partition each,
    keyed by its ``name=value`` folders, else by its path). With ``spec`` (``--keys``), a partition is one value of
    those keys (the files below it, across any other keys, are fitted together). Raises
    FrictidInputError naming what is missing or inconsistent."""
    if not sources:
        raise FrictidInputError("fit --engine dask: give a dataset folder or log files")
    groups: dict[tuple, list[str]] = {}
    for src in sources:
        p = Path(src)
        if p.is_dir():
            files = sorted(f for f in p.rglob("*") if f.is_file() and f.suffix in LOG_SUFFIXES
                           and not any(x.startswith((".", "_")) for x in f.relative_to(p).parts))
            if not files:
                raise FrictidInputError(f"{p}: no .parquet or .csv log below this folder")
            for f in files:
                keys = hive_keys(f, p) or (("file", str(f.relative_to(p))),)
                groups.setdefault(keys, []).append(str(f.resolve()))  # workers may run elsewhere
        elif p.is_file():
            keys = hive_keys(p.resolve(), Path(p.resolve().anchor)) or (("file", str(p)),)
            groups.setdefault(keys, []).append(str(p.resolve()))
        else:
            raise FrictidInputError(f"{src}: no such file or folder")
    names = {tuple(k for k, _ in kv) for kv in groups}
    if len(names) > 1:
        raise FrictidInputError("the dataset's partitions have different keys: "
                                + "; ".join("/".join(n) for n in sorted(names))
                                + " (every log must sit under the same name=value folders)")
    if spec is not None:
        check_keys(spec, [k for k in next(iter(names)) if k != "file"], "the dataset")
        merged: dict[tuple, list[str]] = {}
        for kv, files in groups.items():
            d = dict(kv)
            merged.setdefault(tuple((k, d[k]) for k in spec.names), []).extend(files)
        groups = merged
    return [Partition(kv, tuple(sorted(files))) for kv, files in sorted(groups.items())]


def time_key(names) -> str | None:
    """The key that orders a joint's partitions in time (the default of ``--keys``): date, day, run or
    time, else the last key."""
    names = list(names)
    for k in TIME_KEYS:
        if k in names:
            return k
    return names[-1] if names else None
