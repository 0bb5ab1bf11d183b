"""TOML (or dict) -> Scene, validated before any kernel runs.

Every problem raises ``SceneError`` with one line: ``FILE: KEY: what is wrong (allowed: RANGE)``.
Each table's keys are read with ``tables.Table``; the media's tables by ``media_tables``.
"""

from __future__ import annotations

import copy
import json
import math
import os
import sys

import numpy as np

from . import shapes
from .media_tables import parse_medium
from .model import Camera, Light, Medium, Scene, Surface
from .tables import SceneError, Table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def _camera(data, source) -> Camera:
    t = Table(data, "camera", source)
    cam = Camera(
        origin=t.vec3("origin"),
        target=t.vec3("target"),
        up=t.vec3("up", (0.0, 1.0, 0.0)),
        fov_y=t.number("fov_y", 40.0, 0.0, 180.0, lo_open=True, hi_open=True),
        width=t.number("width", 128, 1, 16384, integer=True),
        height=t.number("height", 96, 1, 16384, integer=True),
        static=t.boolean("static", True),
    )
    t.finish()
    fwd = np.subtract(cam.target, cam.origin)
    if np.linalg.norm(fwd) == 0:
        t.fail("camera.target", "equals camera.origin", "a point other than the origin")
    if np.linalg.norm(np.cross(fwd, cam.up)) <= 1e-6 * np.linalg.norm(fwd) * np.linalg.norm(cam.up):
        t.fail("camera.up", "is parallel to the viewing direction (or zero)",
               "a vector not parallel to target - origin")
    return cam


def _light(data, where, source) -> Light:
    t = Table(data, where, source)
    kind = t.string("type", choices=["point", "spot", "directional"])
    static = t.boolean("static", True)
    if kind == "directional":
        direction = t.vec3("direction")
        if np.linalg.norm(direction) == 0:
            t.fail(t.key("direction"), "is the zero vector", "a non-zero vector")
        light = Light(kind, strength=t.vec3("irradiance", lo=0.0, scalar_ok=True),
                      direction=tuple((np.asarray(direction) / np.linalg.norm(direction)).tolist()))
    else:
        light = Light(kind, strength=t.vec3("intensity", lo=0.0, scalar_ok=True), position=t.vec3("position"))
        if kind == "spot":
            direction = t.vec3("direction")
            if np.linalg.norm(direction) == 0:
                t.fail(t.key("direction"), "is the zero vector", "a non-zero vector")
            light.direction = tuple((np.asarray(direction) / np.linalg.norm(direction)).tolist())
            light.outer_angle = t.number("outer_angle", 30.0, 0.0, 180.0, lo_open=True)
            light.inner_angle = t.number("inner_angle", min(20.0, light.outer_angle), 0.0, light.outer_angle)
    light.static = static
    t.finish()
    return light


def _surface(data, where, source, base_dir) -> Surface:
    t = Table(data, where, source)
    kind = t.string("type", choices=["mesh", "box", "plane", "sphere", "procedural"])
    name = t.string("name", "")
    diffuse = t.vec3("diffuse", (0.7, 0.7, 0.7), lo=0.0, hi=1.0, scalar_ok=True)
    specular = t.number("specular", 0.0, 0.0, 1.0)
    shininess = t.number("shininess", 20.0, 0.0)
    static = t.boolean("static", True)
    if max(diffuse) + specular > 1.0:
        t.fail(t.key("specular"), f"diffuse + specular = {max(diffuse) + specular:g} creates energy",
               "diffuse + specular <= 1")
    colours = None
    if kind == "mesh":
        path = t.path("file", base_dir)
        try:
            v, f = shapes.read_obj(path)
        except (OSError, ValueError) as exc:
            t.fail(t.key("file"), f"cannot read {path!r}: {exc}",
                   "a triangle or polygon .obj file, vertices 3 finite numbers")
    elif kind == "box":
        v, f = shapes.box(t.vec3("center", (0.0, 0.0, 0.0)), t.vec3("size", lo=0.0, lo_open=True))
    elif kind == "plane":
        normal = t.vec3("normal", (0.0, 1.0, 0.0))
        if np.linalg.norm(normal) == 0:
            t.fail(t.key("normal"), "is the zero vector", "a non-zero vector")
        size = t.raw("size", [100.0, 100.0], "[w, h] with w, h > 0", "[w, h]")
        if not isinstance(size, (list, tuple)) or len(size) != 2 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0 for x in size
        ):
            t.fail(t.key("size"), f"expected [w, h], got {size!r}", "[w, h] with w, h > 0")
        v, f = shapes.plane(t.vec3("center", (0.0, 0.0, 0.0)), normal, size)
    elif kind == "sphere":
        v, f = shapes.sphere(t.vec3("center", (0.0, 0.0, 0.0)), t.number("radius", lo=0.0, lo_open=True))
    elif name == "colonnade":
        v, f, colours = shapes.colonnade(t.vec3("center", (0.0, 0.0, 0.0)),
                                         t.number("columns", 8, 1, 64, integer=True),
                                         t.number("segments", 64, 3, 1024, integer=True),
                                         t.number("stacks", 64, 1, 1024, integer=True), diffuse)
    else:
        if name != "cornell_box":
            t.fail(t.key("name"), f"unknown procedural surface {name!r}", "cornell_box | colonnade")
        v, f, colours = shapes.cornell_box(t.vec3("center", (0.0, 0.0, 0.0)),
                                           t.vec3("size", (2.0, 2.0, 2.0), lo=0.0, lo_open=True), diffuse)
    t.finish()
    if colours is None:
        colours = np.tile(np.asarray(diffuse, np.float64), (len(f), 1))
    return Surface(kind, v.astype(np.float32), f.astype(np.int32), colours.astype(np.float32),
                   specular, shininess, name, static)


def scene_from_dict(data: dict, source: str = "<dict>", base_dir: str = ".") -> Scene:
    """Validate a scene given as a dict (the TOML layout; arrays may be numpy)."""
    t = Table(data, "", source)
    name = t.string("name", os.path.splitext(os.path.basename(source))[0] if source != "<dict>" else "scene")
    background = t.vec3("background", (0.0, 0.0, 0.0), lo=0.0, scalar_ok=True)
    camera = _camera(t.raw("camera", allowed="a [camera] table", kind="table"), source)

    def items(key):
        v = t.raw(key, [], f"[[{key}]] tables", "array of tables")
        if not isinstance(v, list):
            t.fail(key, f"must be an array of tables ([[{key}]]), got {type(v).__name__}", f"[[{key}]] tables")
        return v

    lights = [_light(d, f"lights[{i}]", source) for i, d in enumerate(items("lights"))]
    media = [parse_medium(d, f"media[{i}]", source, base_dir) for i, d in enumerate(items("media"))]
    surfaces = [_surface(d, f"surfaces[{i}]", source, base_dir) for i, d in enumerate(items("surfaces"))]
    t.finish()
    if not media and not surfaces and not any(background):
        t.fail("media", "the scene has no media, no surfaces and a black background: nothing to see",
               "at least one medium or surface, or a non-black background")
    return Scene(name, camera, lights, media, surfaces, background, source)


def apply_overrides(data: dict, assignments: list[str], source: str) -> dict:
    """Apply ``key=value`` overrides (dotted keys, list indices as numbers; value in TOML syntax)."""
    data = copy.deepcopy(data)
    for item in assignments:
        if "=" not in item:
            raise SceneError(f"{source}: --set {item!r}: expected key=value (allowed: e.g. camera.width=64)")
        key, value = item.split("=", 1)
        try:
            parsed = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            parsed = value
        node = data
        parts = key.strip().split(".")
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            if isinstance(node, list):
                if not part.isdigit() or int(part) >= len(node):
                    raise SceneError(f"{source}: --set {key}: index {part!r} out of range "
                                     f"(allowed: 0..{len(node) - 1})")
                if last:
                    node[int(part)] = parsed
                else:
                    node = node[int(part)]
            elif isinstance(node, dict):
                if last:
                    node[part] = parsed
                else:
                    node = node.setdefault(part, {})
            else:
                raise SceneError(f"{source}: --set {key}: {part!r} is not inside a table "
                                 "(allowed: a dotted path to a key)")
    return data


def override_items(overrides) -> list[str]:
    """Overrides as the CLI's ``KEY=VALUE`` strings, from those or from a {dotted key: value}
    dict (``{"camera.width": 320, "media.0.sigma_t": [1, 2, 3]}``; values as in TOML)."""
    if overrides is None:
        return []
    if isinstance(overrides, dict):
        return [f"{k}={json.dumps(v.tolist() if hasattr(v, 'tolist') else v)}" for k, v in overrides.items()]
    return list(overrides)


def load_scene(scene, overrides: list[str] | dict | None = None) -> Scene:
    """A Scene from a .toml path, a built-in scene name, a dict, or a Scene (returned as is);
    ``overrides`` (``override_items``) change keys by their dotted path, as ``--set`` does."""
    overrides = override_items(overrides)
    if isinstance(scene, Scene):
        if overrides:
            raise SceneError(f"overrides {', '.join(overrides)}: apply to a scene file, built-in name or dict "
                             "(allowed: for a loaded Scene, dataclasses.replace, or Renderer.update)")
        return scene
    if isinstance(scene, dict):
        return scene_from_dict(apply_overrides(scene, overrides or [], "<dict>"), "<dict>", ".")
    path = os.fspath(scene)
    from .procedural import BUILTIN

    if path in BUILTIN and not os.path.exists(path):
        data = BUILTIN[path]()
        return scene_from_dict(apply_overrides(data, overrides or [], f"<builtin {path}>"), f"<builtin {path}>", ".")
    if not os.path.isfile(path):
        raise SceneError(f"{path}: file not found (allowed: a .toml scene file or a built-in name: "
                         f"{', '.join(sorted(BUILTIN))})")
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc} (allowed: a TOML scene file: a [camera] table and "
                         "[[lights]], [[media]], [[surfaces]] arrays of tables)") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not a text file: byte {exc.start} is not UTF-8 "
                         "(allowed: a UTF-8 TOML scene file)") from None
    return scene_from_dict(apply_overrides(data, overrides or [], path), path, os.path.dirname(os.path.abspath(path)))


def parse_part(part: str, value, source: str = "<update>"):
    """A scene part for ``Renderer.update``: model objects pass through, dicts are validated.

    ``part`` is ``camera`` (a Camera or table), ``lights``, ``medium`` or ``surfaces`` (one
    item or a list of them).
    """
    if part == "camera":
        return value if isinstance(value, Camera) else _camera(value, source)
    parse, kind = {"lights": (lambda d, w: _light(d, w, source), Light),
                   "medium": (lambda d, w: parse_medium(d, w, source, "."), Medium),
                   "surfaces": (lambda d, w: _surface(d, w, source, "."), Surface)}[part]
    items = value if isinstance(value, (list, tuple)) else [value]
    return [v if isinstance(v, kind) else parse(v, f"{part}[{i}]") for i, v in enumerate(items)]
