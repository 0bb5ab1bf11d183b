"""Raymarch: the deterministic single-scattering baseline every technique is compared with.

Per pixel centre, the camera ray is marched from where it enters the media to the nearest
surface (or where it leaves them) in ``steps`` equal steps, or steps of ``step_length``.
Each step evaluates sigma_t and the in-scattered direct light S at its midpoint and adds
T S (1 - exp(-sigma_t dt)) / sigma_t, the exact integral over a step of constant
coefficients (Hillaire 2015), so thin and thick steps both conserve energy. Light reaches
a point through the media (homogeneous media exactly, heterogeneous ones marched with
``shadow_steps`` midpoint steps) and past surfaces (a shadow ray). Surfaces are lit
directly; no light scatters more than once.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .. import device as dev
from ..geometry.camera import PinholeCamera, camera_ray, pinhole
from ..geometry.mesh import SurfaceBuffers, Surfaces, surface_hit
from ..media.volume import Media, MediaBuffers, in_scatter_at, ray_box, sigma_t_at
from ..physics.constants import INF
from ..physics.lights import Light, light_incident
from ..physics.transmittance import transmittance_rgb
from ..pipeline import Setting, timed
from ..shading import light_array, light_transmittance, surface_direct

NAME = "raymarch"
SETTINGS = {
    "steps": Setting(64, 1, 1 << 20, "steps along each camera ray (used when step_length = 0)"),
    "step_length": Setting(0.0, 0.0, 1.0e6, "step length in scene units; 0 = use steps"),
    "shadow_steps": Setting(32, 1, 1 << 20, "steps along each ray toward a light, heterogeneous media"),
}


@wp.struct
class MarchSettings:
    steps: int
    step_length: float
    shadow_steps: int


@wp.func
def step_factor(sigma: float, dt: float) -> float:
    """integral_0^dt exp(-sigma s) ds, stable as sigma -> 0."""
    tau = sigma * dt
    if tau < 1.0e-4:
        return dt * (1.0 - 0.5 * tau)
    return (1.0 - wp.exp(-tau)) / sigma


@wp.kernel
def march_single_scattering(offset: int, cam: PinholeCamera, m: Media, s: Surfaces, lights: wp.array(dtype=Light),
                            background: wp.vec3, st: MarchSettings, image: wp.array(dtype=wp.vec3)):
    tid = wp.tid() + offset
    px = tid % cam.width
    py = tid / cam.width
    o = cam.origin
    d = camera_ray(cam, float(px) + 0.5, float(py) + 0.5)
    rng = wp.uint32(0)  # unused: transmittance is marched, not estimated
    hit, t_surf, n, face = surface_hit(s, o, d, INF)
    a, b = ray_box(o, d, m.all_min, m.all_max)
    ta = wp.max(a, 0.0)
    tb = wp.min(b, t_surf)
    tr = wp.vec3(1.0)
    L = wp.vec3(0.0)
    if ta < tb:
        steps = st.steps
        if st.step_length > 0.0:
            steps = wp.clamp(int(wp.ceil((tb - ta) / st.step_length)), 1, 1 << 20)
        dt = (tb - ta) / float(steps)
        for k in range(steps):
            x = o + (ta + (float(k) + 0.5) * dt) * d
            sig = sigma_t_at(m, x, False)
            if sig[0] > 0.0 or sig[1] > 0.0 or sig[2] > 0.0:
                inscatter = wp.vec3(0.0)
                for l in range(lights.shape[0]):
                    wi, dist, e = light_incident(lights[l], x)
                    if dist > 0.0:
                        tl = light_transmittance(m, s, x, wi, dist, 0, rng, st.shadow_steps)
                        inscatter += wp.cw_mul(wp.cw_mul(in_scatter_at(m, x, wp.dot(d, wi)), e), tl)
                f = wp.vec3(step_factor(sig[0], dt), step_factor(sig[1], dt), step_factor(sig[2], dt))
                L += wp.cw_mul(wp.cw_mul(tr, inscatter), f)
                tr = wp.cw_mul(tr, transmittance_rgb(sig * dt))
    if hit:
        nf = wp.where(wp.dot(n, d) < 0.0, n, -n)
        p = o + t_surf * d
        L += wp.cw_mul(tr, surface_direct(m, s, lights, p, nf, -d, s.material[face], 0, rng, st.shadow_steps))
    else:
        L += wp.cw_mul(tr, background)
    image[tid] = L


def render(scene, device: str, settings: dict, progress: bool = True):
    """Render ``scene``; returns (image H x W x 3 float32, {stage: seconds})."""
    timings: dict = {}
    with timed(timings, "setup", device):
        cam = pinhole(scene.camera)
        media = MediaBuffers(scene, device)
        surfaces = SurfaceBuffers(scene, device)
        lights = light_array(scene, device)
        npix = scene.camera.width * scene.camera.height
        image = wp.zeros(npix, dtype=wp.vec3, device=device)
    st = MarchSettings()
    st.steps, st.step_length, st.shadow_steps = settings["steps"], settings["step_length"], settings["shadow_steps"]
    with timed(timings, "march", device):
        dev.launch(march_single_scattering, npix, [cam, media.struct, surfaces.struct, lights,
                                                   wp.vec3(*scene.background), st, image], device)
    return image.numpy().reshape(scene.camera.height, scene.camera.width, 3), timings
