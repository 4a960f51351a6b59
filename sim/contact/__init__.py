"""IPC contact on the embedded triangle meshes (paper section 4.3; docs/design.md section 6)."""
