"""Conforming: flat garment panels (triangle meshes or pattern outlines) -> quadratic
B-spline patches (docs/design.md section 4b). Entry points: `conform_panel` for one panel,
`conform_all` for a garment with its seams; see pipeline.py for the stages."""

from .boundary import PanelError
from .pipeline import ConformOptions, conform_all, conform_panel

__all__ = ["ConformOptions", "PanelError", "conform_all", "conform_panel"]
