"""Where the tests find the repository's files."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # the repository
ASSETS = ROOT / "assets"  # bundled garments and scenes
SCENES = ASSETS / "scenes"
SHARED_ASSETS = ROOT / ".." / "shared" / "assets"  # the real inputs beside the repository
