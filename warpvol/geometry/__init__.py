"""Triangle meshes (wp.Mesh), cameras, depth and shadow maps."""
