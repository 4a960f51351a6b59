"""Tools the tests share (fixtures stay in tests/conftest.py):

- fd.py: the finite-difference checker every derivative test uses;
- intersections.py: the independent brute-force intersection check, and check_frames.py,
  which runs it on exported frames (python -m tests.support.check_frames DIR);
- scenes.py: small scene texts and seamed panels; panels.py: panel meshes, outlines, OBJ
  files and measures of conformed patches; meshes.py: synthetic meshes for the sinks;
- paths.py: the repository and its assets.
"""
