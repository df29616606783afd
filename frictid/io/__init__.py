"""Logs in and out, parameter files, mapping files."""
