"""All of a scene's surfaces as one ``wp.Mesh`` with a material per triangle."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..physics.brdf import Material
from ..physics.constants import INF
from ..scene.model import Scene


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


class SurfaceBuffers:
    """Owns the ``wp.Mesh`` and material array behind a ``Surfaces`` struct."""

    def __init__(self, scene: Scene, device):
        s = Surfaces()
        verts, faces, mats = [], [], []
        base = 0
        for surf in scene.surfaces:
            verts.append(surf.vertices)
            faces.append(surf.faces + base)
            base += len(surf.vertices)
            for colour in surf.diffuse:
                m = Material()
                m.diffuse = wp.vec3(*colour)
                m.specular = surf.specular
                m.shininess = surf.shininess
                mats.append(m)
        self.mesh = None
        if faces:
            self.mesh = wp.Mesh(
                points=wp.array(np.concatenate(verts).astype(np.float32), dtype=wp.vec3, device=device),
                indices=wp.array(np.concatenate(faces).astype(np.int32).ravel(), dtype=int, device=device),
            )
            s.mesh, s.present = self.mesh.id, 1
        else:
            s.mesh, s.present = wp.uint64(0), 0
            mats = [Material()]
        s.material = wp.array(mats, dtype=Material, device=device)
        self.struct = s
