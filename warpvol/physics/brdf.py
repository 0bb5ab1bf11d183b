"""Surface reflection: Lambertian plus energy-normalised Phong (Lewis 1994).

f(wo, wi) = kd / pi + ks (n + 2) / (2 pi) max(0, dot(reflect(-wo, N), wi))^n, with
kd + ks <= 1 so no energy is created. Surfaces are opaque and two-sided.
"""

import warp as wp

from .constants import INV_2PI, INV_PI


@wp.struct
class Material:
    diffuse: wp.vec3  # kd, Lambertian reflectance per channel
    specular: float  # ks
    shininess: float  # Phong exponent n


@wp.func
def brdf_eval(mat: Material, n: wp.vec3, wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
    """f in 1/sr; ``wo`` points to the viewer, ``wi`` to the light, ``n`` faces wo."""
    f = mat.diffuse * INV_PI
    if mat.specular > 0.0:
        r = 2.0 * wp.dot(wo, n) * n - wo
        c = wp.max(wp.dot(r, wi), 0.0)
        f = f + wp.vec3(mat.specular * (mat.shininess + 2.0) * INV_2PI * wp.pow(c, mat.shininess))
    return f
