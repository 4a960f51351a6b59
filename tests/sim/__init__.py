"""Tests of sim/: the B-spline FEM, energies, contact, seams and the solver."""
