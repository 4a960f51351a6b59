"""Linear triangle FEM baseline: the same energies, Newton and CHOLMOD as the B-spline
simulator on piecewise linear meshes, so comparisons isolate the discretisation."""

from .mesh import TriangleMesh, equilateral_mesh, grid_mesh
from .model import linear_model

__all__ = ["TriangleMesh", "equilateral_mesh", "grid_mesh", "linear_model"]
