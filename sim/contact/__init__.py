"""IPC contact on the embedded triangle meshes (paper section 4.3; DESIGN.md section 6)."""
