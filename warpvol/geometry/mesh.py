"""All of a scene's surfaces as one ``wp.Mesh`` with a material per triangle."""

from __future__ import annotations

import warp as wp

from ..physics.brdf import Material
from ..physics.constants import INF, RAY_EPS


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
    """Whether a surface lies on o + t d for t in (0, dist). A hit closer than RAY_EPS is
    passed over once: a shadow ray leaving a point at a concave edge (a ceiling meeting a
    wall), offset along its own face's normal, starts on the other face's plane, or behind it
    by the hit point's rounding, and would find that face at t ~ 0 and call the point dark."""
    if s.present == 0:
        return False
    q = wp.mesh_query_ray(s.mesh, o, d, dist * 0.9999)
    if q.result and q.t < RAY_EPS:
        skip = q.t + RAY_EPS
        q = wp.mesh_query_ray(s.mesh, o + skip * d, d, dist * 0.9999 - skip)
    return q.result
