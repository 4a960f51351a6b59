"""Tests of viz/: Rerun recordings, renders and the logging overhead."""
