"""Fleets of joint logs: one fit per partition of a dataset (serially or on a Dask cluster) into a trend
store, and each joint's friction over time from that store (``docs/fleet.md``).

- :mod:`.dataset`: partitions of a hive-partitioned folder or a list of files, and their content hashes.
- :mod:`.run`: the fit of one partition, the serial loop and the Dask task graph.
- :mod:`.store`: the trend store (one appendable Parquet table, the parameter files beside it).
- :mod:`.trend`: normalisation, change points, limits.
- :mod:`.page`: the HTML page of a trend.

Only the command line imports this package.
"""
from __future__ import annotations
