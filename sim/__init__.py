"""B-spline FEM cloth simulation (the paper's sections 3 to 5)."""

from . import threads  # noqa: F401  (thread defaults, before CHOLMOD loads)
