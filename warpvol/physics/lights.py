"""Point, spot and directional lights: what reaches a point x.

| kind        | strength  | units            | at x                                     |
|-------------|-----------|------------------|------------------------------------------|
| point       | intensity | W/sr (per RGB)   | irradiance I / d^2 from ``position``     |
| spot        | intensity | W/sr             | I / d^2 times a smoothstep cone falloff  |
| directional | irradiance| W/m^2            | E, arriving against ``direction``        |

``direction`` of a directional light is the way its light travels; of a spot light, the
axis of its cone. The spot falloff is smoothstep(cos_outer, cos_inner, cos(angle to axis)).
"""

import warp as wp

from .constants import INF

POINT = wp.constant(0)
SPOT = wp.constant(1)
DIRECTIONAL = wp.constant(2)

KINDS = {"point": 0, "spot": 1, "directional": 2}


@wp.struct
class Light:
    kind: int
    position: wp.vec3
    direction: wp.vec3  # unit; travel direction (directional) or cone axis (spot)
    strength: wp.vec3  # intensity I (point, spot) or irradiance E (directional)
    cos_inner: float
    cos_outer: float


@wp.func
def spot_falloff(light: Light, cos_axis: float) -> float:
    if cos_axis >= light.cos_inner:
        return 1.0
    if cos_axis <= light.cos_outer:
        return 0.0
    t = (cos_axis - light.cos_outer) / (light.cos_inner - light.cos_outer)
    return t * t * (3.0 - 2.0 * t)


@wp.func
def light_incident(light: Light, x: wp.vec3):
    """Returns (wi, dist, E): unit direction from x to the light, distance to it
    (INF for directional), and the irradiance it delivers to a surface facing it."""
    if light.kind == DIRECTIONAL:
        return -light.direction, INF, light.strength
    to_light = light.position - x
    d2 = wp.dot(to_light, to_light)
    if d2 <= 0.0:
        return wp.vec3(0.0, 1.0, 0.0), 0.0, wp.vec3(0.0)
    dist = wp.sqrt(d2)
    wi = to_light / dist
    e = light.strength / d2
    if light.kind == SPOT:
        e = e * spot_falloff(light, wp.dot(-wi, light.direction))
    return wi, dist, e
