"""pyvista views of warpvol scenes and of techniques' intermediate arrays.

    python -m warpvol view SCENE [--screenshot out.png]

Functions that turn arrays into pyvista meshes (``volume_grid``, ``lattice_grid``,
``particles_mesh``, ``network_mesh``, ``light_glyphs``,
``camera_frustum``, ``depth_surface``, ``slice_plane``), ``technique_actors`` for what
``Renderer.arrays()`` exposes, and one that assembles a whole scene (``scene_plotter``). Techniques
add their own views here as they land. Uses only warpvol's public API.
"""

from .views import (
    camera_frustum,
    depth_surface,
    impostor_layers,
    lattice_grid,
    light_slice_planes,
    light_glyphs,
    network_mesh,
    particles_mesh,
    scene_plotter,
    slice_plane,
    surfaces_mesh,
    technique_actors,
    volume_grid,
)

__all__ = [
    "camera_frustum", "depth_surface", "impostor_layers", "lattice_grid", "light_glyphs", "light_slice_planes",
    "network_mesh", "particles_mesh",
    "scene_plotter", "slice_plane", "surfaces_mesh", "technique_actors", "volume_grid",
]
