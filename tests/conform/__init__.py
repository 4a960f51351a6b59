"""Tests of conform/: panels to B-spline patches, grading, splitting, pleats, placement."""
