"""Arrays to pyvista meshes, and a scene to a plotter.

Volumes follow warpvol's layout: arrays indexed [z, y, x] (x fastest) over an axis-aligned
box. ``volume_grid`` takes cell-centred samples (a grid medium, an extinction volume, an
optical-depth volume per light), ``lattice_grid`` node-centred ones (a baked light volume).
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv

import warpvol as wv


def _channels(values: np.ndarray, spatial: int = 3) -> list[np.ndarray]:
    """Split (D, H, W), (D, H, W, C) or (C, D, H, W)-with-C-first arrays into scalar fields."""
    values = np.asarray(values)
    if values.ndim == spatial:
        return [values]
    if values.ndim == spatial + 1 and values.shape[-1] in (1, 3) and values.shape[0] not in (1,):
        return [values[..., c] for c in range(values.shape[-1])]
    return [values[c] for c in range(values.shape[0])]


def _set_fields(data, fields: list[np.ndarray], name: str) -> None:
    """Store each field as ``name[i]`` (when there are several) and their mean as ``name``,
    the active scalars, in a pyvista cell- or point-data collection."""
    for i, f in enumerate(fields):
        if len(fields) > 1:
            data[f"{name}[{i}]"] = np.ascontiguousarray(f, np.float32).ravel()
    data[name] = np.mean([np.asarray(f, np.float32) for f in fields], axis=0).ravel()
    data.active_scalars_name = name


def volume_grid(values, bounds_min, bounds_max, name: str = "sigma_t") -> pv.ImageData:
    """Cell-centred samples over [bounds_min, bounds_max] as an ImageData with cell data.

    ``values``: (D, H, W) scalars, (D, H, W, 3) RGB (stored per channel as ``name[c]`` and
    their mean as ``name``), or (L, D, H, W), one field per light (``name[l]``).
    """
    fields = _channels(values)
    d, h, w = fields[0].shape
    lo, hi = np.asarray(bounds_min, float), np.asarray(bounds_max, float)
    grid = pv.ImageData(dimensions=(w + 1, h + 1, d + 1), spacing=tuple((hi - lo) / (w, h, d)), origin=tuple(lo))
    _set_fields(grid.cell_data, fields, name)
    return grid


def lattice_grid(values, bounds_min, bounds_max, name: str = "transmittance") -> pv.ImageData:
    """Node-centred samples (nodes on the box's corners) as an ImageData with point data."""
    fields = _channels(values)
    d, h, w = fields[0].shape
    lo, hi = np.asarray(bounds_min, float), np.asarray(bounds_max, float)
    spacing = tuple((hi - lo) / np.maximum(np.array((w, h, d)) - 1, 1))
    grid = pv.ImageData(dimensions=(w, h, d), spacing=spacing, origin=tuple(lo))
    _set_fields(grid.point_data, fields, name)
    return grid


def particles_mesh(positions, radius, scalars=None, name: str = "radiance", resolution: int = 12) -> pv.PolyData:
    """One sphere per particle; ``scalars`` (N,) or (N, 3) colour them (RGB shown as its mean)."""
    pts = pv.PolyData(np.asarray(positions, np.float32).reshape(-1, 3))
    if scalars is not None:
        s = np.asarray(scalars, np.float32)
        pts.point_data[name] = s.mean(axis=1) if s.ndim == 2 else s
    r = float(np.mean(radius))
    return pts.glyph(geom=pv.Sphere(radius=r, theta_resolution=resolution, phi_resolution=resolution),
                     scale=False, orient=False)


def network_mesh(positions, visible, direction: int, alpha=None) -> pv.PolyData:
    """Edges of a visibility network for one direction: p -> visible[p, direction].

    ``visible``: (N, D) particle indices, -1 where nothing is seen (light from outside);
    ``alpha``: optional (N, D) opacities, kept as cell data on the edges.
    """
    positions = np.asarray(positions, np.float32)
    target = np.asarray(visible)[:, direction]
    src = np.nonzero(target >= 0)[0]
    lines = np.column_stack([np.full(len(src), 2), src, target[src]]).ravel()
    mesh = pv.PolyData(positions, lines=lines if len(src) else None)
    if alpha is not None and len(src):
        mesh.cell_data["alpha"] = np.asarray(alpha, np.float32)[src, direction]
    return mesh


def surfaces_mesh(scene) -> pv.PolyData | None:
    """The scene's surfaces as one triangle mesh with per-face diffuse colour (``diffuse``)."""
    verts, faces, colours, base = [], [], [], 0
    for s in scene.surfaces:
        verts.append(s.vertices)
        faces.append(np.column_stack([np.full(len(s.faces), 3), s.faces + base]))
        colours.append(s.diffuse)
        base += len(s.vertices)
    if not verts:
        return None
    mesh = pv.PolyData(np.concatenate(verts).astype(np.float32), np.concatenate(faces).ravel())
    mesh.cell_data["diffuse"] = (np.clip(np.concatenate(colours), 0, 1) * 255).astype(np.uint8)
    return mesh


def light_glyphs(scene, size: float = 0.15) -> list[tuple[pv.PolyData, tuple]]:
    """(mesh, colour) per light: a sphere for a point light, a cone along a spot light's axis,
    an arrow along a directional light's travel direction, coloured by the light's hue."""
    out = []
    for light in scene.lights:
        rgb = np.asarray(light.strength, float)
        colour = tuple(rgb / rgb.max()) if rgb.max() > 0 else (1.0, 1.0, 1.0)
        if light.type == "point":
            mesh = pv.Sphere(radius=size, center=light.position)
        elif light.type == "spot":
            height = 3 * size
            axis = np.asarray(light.direction, float)
            mesh = pv.Cone(center=np.asarray(light.position) + 0.5 * height * axis, direction=-axis, height=height,
                           radius=height * math.tan(math.radians(light.outer_angle)))
        else:
            d = np.asarray(light.direction, float)
            start = np.asarray(scene.camera.target, float) - 8 * size * d
            mesh = pv.Arrow(start=start, direction=d, scale=6 * size)
        out.append((mesh, colour))
    return out


def camera_frustum(camera, depth: float | None = None) -> pv.PolyData:
    """The camera's view pyramid, from its origin out to ``depth`` (default: to the target)."""
    o = np.asarray(camera.origin, float)
    fwd = np.asarray(camera.target, float) - o
    depth = depth or float(np.linalg.norm(fwd))
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, camera.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    ty = math.tan(math.radians(camera.fov_y) / 2)
    tx = ty * camera.width / camera.height
    corners = [o + depth * (fwd + sx * tx * right + sy * ty * up) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    pts = np.vstack([o, *corners])
    lines = [2, 0, 1, 2, 0, 2, 2, 0, 3, 2, 0, 4, 2, 1, 2, 2, 2, 3, 2, 3, 4, 2, 4, 1]
    return pv.PolyData(pts, lines=np.array(lines))


def _medium_actor(plotter: pv.Plotter, scene, medium, resolution: int):
    if medium.type == "homogeneous":
        if medium.shape == "box":
            mesh = pv.Box(bounds=np.ravel(np.column_stack([np.subtract(medium.center, np.multiply(medium.size, 0.5)),
                                                           np.add(medium.center, np.multiply(medium.size, 0.5))])))
        else:
            mesh = pv.Sphere(radius=medium.radius, center=medium.center)
        plotter.add_mesh(mesh, color="lightsteelblue", opacity=0.15, label="homogeneous medium")
    elif medium.type == "particles":
        plotter.add_mesh(particles_mesh(medium.positions, medium.radius, resolution=8), color="white", opacity=0.6,
                         label=f"{len(medium.positions)} particles")
    else:  # grid or rbf: sample its extinction and show it as a volume
        one = wv.Scene(scene.name, scene.camera, media=[medium])
        sigma, lo, hi = wv.extinction_volume(one, resolution)
        grid = volume_grid(sigma, lo, hi)
        plotter.add_volume(grid, scalars="sigma_t", cmap="bone", opacity="sigmoid", show_scalar_bar=False)


def scene_plotter(scene, off_screen: bool = False, window_size=(960, 720), resolution: int = 48) -> pv.Plotter:
    """A plotter showing ``scene`` (a Scene, path, built-in name or dict): media as volumes
    (grid and RBF extinction sampled at ``resolution`` cells), particles as spheres,
    surfaces with their diffuse colour, lights as glyphs, and the camera's frustum."""
    scene = wv.load_scene(scene)
    plotter = pv.Plotter(off_screen=off_screen, window_size=window_size)
    plotter.set_background("black" if not any(scene.background) else tuple(min(1.0, c) for c in scene.background))
    surfaces = surfaces_mesh(scene)
    if surfaces is not None:
        plotter.add_mesh(surfaces, scalars="diffuse", rgb=True, opacity=0.6)
    for medium in scene.media:
        _medium_actor(plotter, scene, medium, resolution)
    for (mesh, colour), light in zip(light_glyphs(scene, size=0.05 * _extent(scene)), scene.lights):
        # a spot's cone is see-through (what sits under the lamp stays visible), its edges drawn
        spot = light.type == "spot"
        plotter.add_mesh(mesh, color=colour, opacity=0.35 if spot else 1.0, show_edges=spot, edge_color=colour)
    plotter.add_mesh(camera_frustum(scene.camera), color="yellow", line_width=2)
    # the title placed in pixels inside the top edge (the corner anchor cut its top off)
    ink = "black" if sum(scene.background) > 1.5 else "white"  # against the background drawn
    plotter.add_text(scene.name, position=(10, window_size[1] - 28), font_size=10, color=ink, name="title")
    # look from behind the scene camera's right shoulder, then fit everything in view
    c = scene.camera
    fwd = np.subtract(c.target, c.origin) / np.linalg.norm(np.subtract(c.target, c.origin))
    right = np.cross(fwd, c.up) / np.linalg.norm(np.cross(fwd, c.up))
    eye_dir = -fwd + 0.8 * right + 0.6 * np.cross(right, fwd)
    plotter.camera_position = [tuple(np.asarray(c.target) + eye_dir), c.target, c.up]
    plotter.reset_camera()
    plotter.camera.zoom(1.5)
    return plotter


def _extent(scene) -> float:
    pts = [np.asarray(scene.camera.origin), np.asarray(scene.camera.target)]
    for s in scene.surfaces:
        pts += [s.vertices.min(0), s.vertices.max(0)]
    return float(np.ptp(np.vstack(pts), axis=0).max()) or 1.0


def depth_surface(points, distance=None, name: str = "distance") -> pv.PolyData:
    """A shadow map's depth surface: the world points its texel rays hit (escaped rays dropped),
    coloured by their distance from the light."""
    pts = np.asarray(points, np.float32)
    keep = np.all(np.abs(pts) < 1e29, axis=1)
    cloud = pv.PolyData(pts[keep])
    if distance is not None:
        cloud.point_data[name] = np.asarray(distance, np.float32)[keep]
    return cloud


def slice_plane(values, corners, name: str = "radiance") -> pv.StructuredGrid:
    """An (H, W) or (H, W, 3) field sampled at cell centres of the parallelogram ``corners``
    (4 x 3: origin, +u, +u+v, +v) as a surface with cell data (RGB shown as its mean)."""
    v = np.asarray(values, np.float32)
    h, w = v.shape[:2]
    c = np.asarray(corners, np.float64)
    s, t = np.meshgrid(np.linspace(0, 1, w + 1), np.linspace(0, 1, h + 1))
    pts = c[0] + s[..., None] * (c[1] - c[0]) + t[..., None] * (c[3] - c[0])
    grid = pv.StructuredGrid(pts[..., 0], pts[..., 1], pts[..., 2])
    field = v.mean(axis=2) if v.ndim == 3 else v
    grid.cell_data[name] = field.ravel()  # VTK orders cells with u fastest, like our (v, u) arrays
    return grid


def technique_actors(plotter: pv.Plotter, technique: str, arrays: dict) -> pv.Plotter:
    """Add what ``technique`` exposes through ``Renderer.arrays(for_view=True)`` to a plotter
    (nothing for a technique without a view here)."""
    view = _TECHNIQUE_VIEWS.get(technique)
    if view is not None:
        view(plotter, arrays)
    return plotter


def _light_shafts_actors(plotter: pv.Plotter, arrays: dict) -> None:
    """Each light's shadow-map depth surface, and the lit slice through the camera's target."""
    for i, pts in enumerate(arrays.get("shadow_points", [])):
        cloud = depth_surface(pts, arrays["shadow_distance"][i])
        if cloud.n_points:
            plotter.add_mesh(cloud, scalars="distance", cmap="viridis", point_size=2, show_scalar_bar=False)
    if "lit_slice" in arrays:
        grid = slice_plane(arrays["lit_slice"], arrays["lit_slice_corners"])
        plotter.add_mesh(grid, scalars="radiance", cmap="inferno", opacity=0.85, show_scalar_bar=False,
                         log_scale=False)


def _rbf_propagation_actors(plotter: pv.Plotter, arrays: dict) -> None:
    """|OPV - marched| per cell for the first light; the extinction when there is no light."""
    if "optical_depth_exact" in arrays:
        err = np.abs(arrays["optical_depth"][0] - arrays["optical_depth_exact"][0])[..., 0]
        grid = volume_grid(err, *arrays["bounds"], name="optical depth error")
        plotter.add_volume(grid, scalars="optical depth error", cmap="magma", opacity="linear",
                           show_scalar_bar=True)
    elif "extinction" in arrays:
        plotter.add_volume(volume_grid(arrays["extinction"], *arrays["bounds"]), scalars="sigma_t", cmap="bone",
                           opacity="sigmoid", show_scalar_bar=False)


def _illumination_network_actors(plotter: pv.Plotter, arrays: dict) -> None:
    """Particles by radiance, and the edges of one direction of the network."""
    pos = arrays["positions"]
    cloud = pv.PolyData(np.asarray(pos, np.float32))
    out = arrays.get("outgoing")
    radiance = arrays["radiance"].mean(axis=1) if out is None else out
    cloud.point_data["radiance"] = np.asarray(radiance, np.float32) @ np.float32([0.2126, 0.7152, 0.0722])
    plotter.add_mesh(cloud, scalars="radiance", cmap="inferno", render_points_as_spheres=True, point_size=9,
                     show_scalar_bar=True)
    d = arrays.get("view_direction", 0)
    edges = network_mesh(pos, arrays["visibility"], d, arrays["alpha"][..., 0])
    if edges.n_cells:
        plotter.add_mesh(edges, scalars="alpha", cmap="viridis", line_width=2, show_scalar_bar=False)


def impostor_layers(centre, frame, reach: float, alpha, front, back) -> list[pv.PolyData]:
    """A block's depth impostor as three layers in the world: its opacity on the plane through
    the block's centre facing the camera, and its front and back depths as surfaces (the
    texels the block covers)."""
    fwd, right, up = (np.asarray(v, np.float64) for v in frame)
    T = alpha.shape[0]
    c = (np.arange(T) + 0.5) / T * 2.0 - 1.0
    u, v = np.meshgrid(c * reach, c * reach)
    base = np.asarray(centre, np.float64) + u[..., None] * right + v[..., None] * up
    plane = pv.StructuredGrid(*(base[..., k] for k in range(3)))
    plane.point_data["opacity"] = np.asarray(alpha, np.float32).mean(-1).ravel(order="F")
    covered = np.asarray(alpha).mean(-1) > 0
    layers = [plane]
    for depth, name in ((front, "front"), (back, "back")):
        pts = (base + np.asarray(depth)[..., None] * fwd)[covered]
        layers.append(depth_surface(pts, np.asarray(depth)[covered], name=name))
    return layers


def light_slice_planes(face: dict, slices) -> list[pv.StructuredGrid]:
    """The light-pass slices of one face as planes across the light's frame, each coloured by
    the opacity accumulated up to its depth (1 - e^-tau)."""
    M, _, C, _ = slices.shape
    o, fwd, right, up = (np.asarray(face[k], np.float64) for k in ("origin", "forward", "right", "up"))
    half, near, far = float(face["half"]), float(face["near"]), float(face["far"])
    c = (np.arange(M) + 0.5) / M * 2.0 - 1.0
    u, v = np.meshgrid(c, c)  # (j, i): v down the rows, u along them
    out = []
    for k in range(1, C):
        t = near + k * (far - near) / (C - 1)
        if face["ortho"]:
            pts = o + half * (u[..., None] * right + v[..., None] * up) + t * fwd
        else:
            d = fwd + half * (u[..., None] * right + v[..., None] * up)
            pts = o + t * d / np.linalg.norm(d, axis=-1, keepdims=True)
        grid = pv.StructuredGrid(*(pts[..., a] for a in range(3)))
        grid.point_data["opacity"] = (1.0 - np.exp(-slices[:, :, k].mean(-1))).astype(np.float32).ravel(order="F")
        out.append(grid)
    return out


def _depth_impostors_actors(plotter: pv.Plotter, arrays: dict) -> None:
    """The instances' bounding spheres, one block's impostor layers, and the light slices."""
    centres = np.asarray(arrays["instances"], np.float32)
    if len(centres):
        plotter.add_mesh(pv.PolyData(centres), color="white", render_points_as_spheres=True, point_size=6)
    if arrays.get("impostor_instance", -1) >= 0:
        i = arrays["impostor_instance"]
        layers = impostor_layers(centres[i], arrays["impostor_frame"], float(arrays["instance_reach"][i]),
                                 arrays["impostor_alpha"], arrays["impostor_front"], arrays["impostor_back"])
        plotter.add_mesh(layers[0], scalars="opacity", cmap="gray", opacity=0.8, show_scalar_bar=False)
        for layer, cmap in zip(layers[1:], ("viridis", "plasma")):
            if layer.n_points:
                plotter.add_mesh(layer, cmap=cmap, point_size=4, show_scalar_bar=False)
    for face, slices in zip(arrays.get("light_faces", []), arrays.get("light_slices", [])):
        for grid in light_slice_planes(face, slices):
            plotter.add_mesh(grid, scalars="opacity", cmap="Blues", opacity=0.25, show_scalar_bar=False)


_TECHNIQUE_VIEWS = {"light_shafts": _light_shafts_actors, "rbf_propagation": _rbf_propagation_actors,
                    "illumination_network": _illumination_network_actors,
                    "depth_impostors": _depth_impostors_actors}
