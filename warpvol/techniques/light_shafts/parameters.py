"""The light shafts' kernel parameters: what the surface pass (``SurfacePass``) and the march
(``ShaftSettings``) read of the technique's settings and the scene, as Warp structs, and how
the host fills them."""

from __future__ import annotations

import warp as wp

from .view_geometry import pixel_width


@wp.struct
class ShaftSettings:
    """The march's settings (``SETTINGS``), with ``block`` the M the image allows."""
    steps: int
    block: int
    jitter: int
    scattering: int
    shadow_steps: int
    seed: int
    spacing: int
    has_depth: int  # 0 when the scene has no surfaces (depth pass skipped)
    near: float  # a point or spot light's ball, marched per pixel: its radius per unit distance from the camera
    ball_floor: float  # the ball's least radius, set per pixel by the march (``BALL_PERIODS``)
    edges: int  # 1: a pixel at a depth edge marches all N samples itself (the depth-aware block sum)
    edge_tolerance: float


@wp.struct
class SurfacePass:
    """What the surface pass reads besides the scene's buffers: the steps toward each light through
    grid media, the midpoints along the view ray in heterogeneous media (as the march's), and the
    background seen where no surface is."""
    shadow_steps: int
    view_steps: int
    background: wp.vec3


def shaft_settings(cfg, block: int, cam, has_depth: bool) -> ShaftSettings:
    """The march's settings ``cfg`` with M = ``block`` (``LightShafts.effective_block``) for the
    camera ``cam``; ``has_depth``: the scene has surfaces."""
    st = ShaftSettings()
    st.steps, st.block, st.jitter = cfg["steps"], block, cfg["jitter"]
    st.scattering, st.shadow_steps, st.seed = cfg["scattering"], cfg["shadow_steps"], cfg["seed"]
    st.spacing = cfg["spacing"]
    st.has_depth = int(has_depth)
    st.near = cfg["light_ball"] * st.block * pixel_width(cam)
    st.ball_floor = 0.0
    st.edges = int(cfg["edges"] == 1 and has_depth)
    st.edge_tolerance = cfg["edge_tolerance"]
    return st


def surface_pass(cfg, background) -> SurfacePass:
    """The surface pass's settings ``cfg`` and the scene's ``background`` (RGB)."""
    sp = SurfacePass()
    sp.shadow_steps, sp.view_steps, sp.background = cfg["shadow_steps"], cfg["steps"], wp.vec3(*background)
    return sp
