"""What every sweep module uses: the ``Sweep`` record, the papers' tables, a row's score against
the reference and a paper row's figure."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

import warpvol as wv

from ..harness import reference_image

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


PAPER_TABLES = tomllib.loads((Path(__file__).resolve().parent.parent / "paper_tables.toml").read_text())


@dataclass
class Sweep:
    """A named list of independent points and how to measure one.

    ``grid(quick)`` gives the points (parameter dicts); ``measure(params, device, quick)``
    returns the row's measured fields. ``paper`` is the table's path in paper_tables.toml
    and ``figure(table, params)`` the paper's number for a point. ``kind`` picks the report:
    ``paper``, ``accuracy`` or ``overhead``.
    """

    name: str
    doc: str
    technique: str
    kind: str
    grid: Callable[[bool], list[dict]]
    measure: Callable[[dict, str, bool], dict]
    paper: tuple[str, ...] = ()
    figure: Callable[[dict, dict], object] | None = None
    note: str = ""  # what the report adds below its sections: how to read the rows

    def points(self, quick: bool = False) -> list[dict]:
        return self.grid(quick)

    def table(self) -> dict | None:
        node = PAPER_TABLES
        for key in self.paper:
            node = node[key]
        return node if self.paper else None

    def paper_figure(self, params: dict):
        return self.figure(self.table(), params) if self.figure and self.paper else None


def row_fps(table: dict, params: dict):
    for row in table["rows"]:
        if all(row.get(k) == v for k, v in params.items() if k in row):
            return row["fps"]
    return None


def score(row: dict, scene, device: str, spp: int, max_bounces: int = 1, pixel_area: int = 0,
          error_map: bool = False) -> np.ndarray:
    """Add to ``row`` the relative RMSE (and HDR-FLIP) of its frame against the reference at pixel centres
    (``max_bounces`` 1: single scattering, what the real-time techniques compute, without
    their error; two seeds of ``spp``), raw and with the reference's own noise removed: that
    noise adds in quadrature, E[err^2 to a noisy ref] = err^2 + floor^2. With ``error_map``, the
    row also shows where its FLIP error lies (``images["flip"]``, false colour, written as a PNG
    beside the sweep's JSON). Returns the reference."""
    ref, floor = reference_image(scene, device, spp=spp, max_bounces=max_bounces, pixel_area=pixel_area)
    row["rel_rmse"] = wv.relative_rmse(row["frame"].image, ref)
    row["rel_rmse_corrected"] = max(row["rel_rmse"] ** 2 - floor**2, 0.0) ** 0.5
    if error_map:  # the second measure (metrics.hdr_flip), and its map
        row["hdr_flip"], flip_map = wv.hdr_flip(row["frame"].image, ref, error_map=True)
        row.setdefault("images", {})["flip"] = display_to_linear(flip_map)
    else:
        row["hdr_flip"] = wv.hdr_flip(row["frame"].image, ref)
    row["reference"] = {"spp": 2 * spp, "max_bounces": max_bounces, "pixel_area": pixel_area, "rel_rmse_floor": floor}
    row["scene"] = f"{scene.name} {scene.camera.width}x{scene.camera.height}"
    return ref


def display_to_linear(image: np.ndarray) -> np.ndarray:
    """The sRGB decoding of a display-ready image (FLIP's false colours), so that ``save_image``,
    which encodes linear radiance as sRGB, writes the colours as they are."""
    c = np.clip(np.asarray(image, np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def score_against_reference(row: dict, scene, device: str, spp: int) -> dict:
    """``score`` in single scattering; returns the row."""
    score(row, scene, device, spp)
    return row


def pixel_directions(cam) -> np.ndarray:
    """(H, W, 3) unit directions of a pinhole camera's rays through the pixel centres (numpy, as
    the kernels' ``view_ray``), for masks a sweep measures over."""
    o = np.asarray(cam.origin, float)
    f = np.asarray(cam.target, float) - o
    f /= np.linalg.norm(f)
    rgt = np.cross(f, cam.up)
    rgt /= np.linalg.norm(rgt)
    up = np.cross(rgt, f)
    th = np.tan(np.radians(cam.fov_y) / 2)
    px, py = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    sx, sy = 2 * px / cam.width - 1, 1 - 2 * py / cam.height
    d = f + sx[..., None] * rgt * th * cam.width / cam.height + sy[..., None] * up * th
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def near_point(cam, point, angle: float) -> np.ndarray:
    """(H, W) mask of the pixels whose ray passes ``point`` (in front of the camera) closer than
    ``angle`` radians as seen from the camera: a light's core on the image."""
    rel = np.asarray(point, float) - np.asarray(cam.origin, float)
    cos = pixel_directions(cam) @ (rel / np.linalg.norm(rel))
    return cos > np.cos(angle)
