"""Every exception frictid raises on purpose.

Each message says what is wrong, where (file, column, row, key) and how to fix it. Only the CLI turns
these into exit codes: :class:`FrictidInputError` and its subclasses give exit code 2. Every one pickles
to the same class and message (an error raised in a worker process reaches the caller unchanged).
"""
from __future__ import annotations


class FrictidInputError(ValueError):
    """Bad usage or bad input: the user can fix it. Exit code 2."""


class LogFormatError(FrictidInputError):
    """A joint log cannot be read or fails validation. Collects every problem found."""

    def __init__(self, path: str, problems: list[str]):
        self.path = path
        self.problems = list(problems)
        head = f"{path}: " if path else ""
        if len(self.problems) == 1:
            msg = head + self.problems[0]
        else:
            msg = head + f"{len(self.problems)} problems:\n" + "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(msg)

    def __reduce__(self):
        """Pickled as its path and problems (e.g. raised in a worker process, raised again in the caller)."""
        return type(self), (self.path, self.problems)


def combined_log_error(found) -> LogFormatError | None:
    """One :class:`LogFormatError` for the problems of several logs read apart (e.g. the joints of one file
    read by different workers), given as (file, problems) pairs: per file, in order, each problem once.
    None when there are none."""
    per_file: dict[str, list[str]] = {}
    for path, problems in found:
        seen = per_file.setdefault(path, [])
        seen += [p for p in problems if p not in seen]
    if not per_file:
        return None
    return LogFormatError("", [str(LogFormatError(path, probs)) for path, probs in per_file.items()])


class ConfigError(FrictidInputError):
    """A plant, recipe, mapping or parameter file is invalid."""


class NotIdentifiableError(FrictidInputError):
    """The data cannot support what was asked (used where a verdict file cannot be written)."""


class QualityGateError(Exception):
    """A quality gate (``frictid compare`` tolerance) failed. Exit code 3."""
