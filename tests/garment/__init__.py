"""Tests of garment/: scenes, the command line, benchmarks, long runs and whole garments."""
