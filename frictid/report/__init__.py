"""The HTML report (layer 3): one self-contained file per identification.

:func:`build_report` returns the HTML of a parameter file (schema 1) and, when given, the logs it came
from; :func:`write_report` writes it atomically. Figures are matplotlib (Agg, imported only when a report
is built) rendered to inline SVG or PNG; the page is a jinja2 template shipped in ``templates/``. See
``docs/report.md``.
"""
from __future__ import annotations

__all__ = ["build_report", "write_report"]


def build_report(params, logs=None, **kw) -> str:
    """The report as an HTML string; see :func:`frictid.report.build.build_report`."""
    from .build import build_report as _build
    return _build(params, logs, **kw)


def write_report(path, params, logs=None, **kw) -> int:
    """Write the report atomically to ``path``; see :func:`frictid.report.build.write_report`."""
    from .build import write_report as _write
    return _write(path, params, logs, **kw)
