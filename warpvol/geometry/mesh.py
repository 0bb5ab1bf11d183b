"""All of a scene's surfaces as one ``wp.Mesh`` with a material per triangle."""

from __future__ import annotations

import warp as wp

from ..physics.brdf import Material
from ..physics.constants import INF


@wp.struct
class Surfaces:
    mesh: wp.uint64
    present: int  # 0 when the scene has no surfaces (mesh is then unused)
    material: wp.array(dtype=Material)  # per triangle


@wp.func
def surface_hit(s: Surfaces, o: wp.vec3, d: wp.vec3, t_max: float):
    """Nearest hit along o + t d, t in (0, t_max): (hit, t, unit geometric normal, face)."""
    if s.present == 0:
        return False, INF, wp.vec3(0.0, 1.0, 0.0), int(-1)
    q = wp.mesh_query_ray(s.mesh, o, d, t_max)
    if q.result:
        return True, q.t, wp.normalize(q.normal), q.face
    return False, INF, wp.vec3(0.0, 1.0, 0.0), int(-1)


@wp.func
def occluded(s: Surfaces, o: wp.vec3, d: wp.vec3, dist: float) -> bool:
    if s.present == 0:
        return False
    q = wp.mesh_query_ray(s.mesh, o, d, dist * 0.9999)
    return q.result
