"""Tools the tests share: finite differences, scenes, panels, synthetic meshes, and the
independent intersection check (also run on exported frames: python -m tests.support.check_frames DIR)."""
