"""The HTML report (layer 3): one self-contained file per identification.

:func:`build_report` returns the HTML of a parameter file (schema 1) and, when given, the logs it came
from; :func:`write_report` writes it atomically. Figures are matplotlib (Agg, imported only when a figure
is drawn) rendered to inline SVG or PNG; the page is a jinja2 template shipped in ``templates/``. See
``docs/report.md``.
"""
from __future__ import annotations

from .build import build_report, write_report

__all__ = ["build_report", "write_report"]
