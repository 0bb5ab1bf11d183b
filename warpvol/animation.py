"""Animations: a camera orbit or dolly, or a light going round, rendered through one
``Renderer``, which re-runs only the stages a frame's change feeds (an orbit re-runs the
camera's; the medium's and the lights' stay cached), and written as a GIF, an MP4 or a folder
of PNG frames.

    import warpvol as wv
    anim = wv.animate("fog-box", "light_shafts", path="orbit", frames=30, out="orbit.gif")
    anim.frames          # 30 H x W x 3 float32 images
    anim.summary()       # time per frame, and per stage how often it ran and was cached

``python -m warpvol animate fog-box --technique light_shafts --orbit 30 --out orbit.gif``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from .image import save_image, tonemap
from .pipeline import SettingsError
from .renderer import Renderer

PATHS = ("orbit", "dolly", "light")
VIDEO = (".gif", ".mp4")


@dataclass
class Animation:
    """The frames (H x W x 3 float32, linear), each frame's wall time in seconds, and per stage
    how many frames it ``ran``, was ``cached`` or ``skipped``."""

    technique: str
    path: str
    frames: list = field(default_factory=list)
    seconds: list = field(default_factory=list)
    stages: dict = field(default_factory=dict)

    def summary(self) -> str:
        """One line of times (the first frame apart: it compiles and uploads) and one per stage."""
        n = len(self.frames)
        rest = self.seconds[1:]
        after = f", then {np.mean(rest):.3f} s a frame ({1.0 / max(np.mean(rest), 1e-9):.1f} FPS)" if rest else ""
        lines = [f"{n} frames ({self.path}): first {self.seconds[0]:.2f} s{after}"]
        for stage, counts in self.stages.items():
            lines.append(f"  {stage:<14} " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
        return "\n".join(lines)


def rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """v rotated by angle about the unit axis (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * np.dot(axis, v) * (1.0 - c)


def _updates(scene, path: str, frames: int) -> list[dict]:
    """``Renderer.update`` arguments for each frame of the path (the first: the scene as is)."""
    cam = scene.camera
    origin, target = np.asarray(cam.origin, float), np.asarray(cam.target, float)
    up = np.asarray(cam.up, float) / np.linalg.norm(cam.up)
    out = []
    for k in range(frames):
        if path == "orbit":  # once round the target, about the camera's up
            o = target + rotate(origin - target, up, 2.0 * math.pi * k / frames)
            out.append({"camera": {"origin": o.tolist()}})
        elif path == "dolly":  # halfway in toward the target
            o = target + (origin - target) * (1.0 - 0.5 * k / max(frames - 1, 1))
            out.append({"camera": {"origin": o.tolist()}})
        else:  # every light once round the target, about the camera's up
            angle = 2.0 * math.pi * k / frames
            lights = [dataclasses.replace(
                li, position=tuple(target + rotate(np.asarray(li.position) - target, up, angle)),
                direction=tuple(rotate(np.asarray(li.direction, float), up, angle))) for li in scene.lights]
            out.append({"lights": lights})
    return out


def check_output(out: str) -> str:
    """The kind of output ``out`` names: "gif", "mp4" or "frames" (a folder); refuses others."""
    ext = os.path.splitext(out)[1].lower()
    if ext in VIDEO:
        folder = os.path.dirname(os.path.abspath(out))
        if not os.path.isdir(folder):
            raise ValueError(f"{out}: folder {folder!r} does not exist (allowed: a path in an existing folder)")
        module, what = ("imageio_ffmpeg", "imageio-ffmpeg") if ext == ".mp4" else ("PIL", "Pillow")
        try:
            __import__(module)
        except ImportError:
            raise ValueError(f"{out}: writing {ext[1:].upper()} needs {what} (fix: pip install 'warpvol[video]'; "
                             "or a folder for PNG frames)") from None
        return ext[1:]
    if ext:
        raise ValueError(f"{out}: unknown animation type {ext!r} (allowed: .gif, .mp4, or a folder for PNG frames)")
    return "frames"


def save_animation(out: str, frames: list, fps: float = 24.0, exposure: float = 0.0) -> None:
    """Write frames as a GIF (Pillow), an MP4 (imageio-ffmpeg) or PNGs ``frame_0000.png``, ...
    in the folder ``out`` (made if missing)."""
    kind = check_output(out)
    if kind == "frames":
        os.makedirs(out, exist_ok=True)
        for k, img in enumerate(frames):
            save_image(os.path.join(out, f"frame_{k:04d}.png"), img, exposure)
        return
    rgb = [tonemap(img, exposure) for img in frames]
    if kind == "gif":
        from PIL import Image

        images = [Image.fromarray(x) for x in rgb]
        images[0].save(out, save_all=True, append_images=images[1:], duration=round(1000.0 / fps), loop=0)
        return
    import imageio_ffmpeg

    h, w, _ = rgb[0].shape
    writer = imageio_ffmpeg.write_frames(out, (w, h), fps=fps, macro_block_size=1, pix_fmt_out="yuv420p")
    writer.send(None)
    for x in rgb:
        writer.send(np.ascontiguousarray(x))
    writer.close()


def animate(scene, technique: str = "light_shafts", path: str = "orbit", frames: int = 30, device: str | None = None,
            progress: bool = False, out: str | None = None, fps: float = 24.0, exposure: float = 0.0,
            overrides=None, **settings) -> Animation:
    """Render ``frames`` frames of ``scene`` along ``path`` ("orbit": the camera once round its
    target; "dolly": the camera halfway in; "light": the lights once round the target) through
    one Renderer, and write them to ``out`` if given (``save_animation``). Settings and
    ``overrides`` as for ``render``."""
    if path not in PATHS:
        raise SettingsError(f"animate: unknown path {path!r} (allowed: {', '.join(PATHS)})")
    if not isinstance(frames, int) or not 1 <= frames <= 100000:
        raise SettingsError(f"animate: frames {frames!r} is out of range (allowed: an integer in [1, 100000])")
    if out is not None:
        check_output(out)
    r = Renderer(scene, technique, device, overrides=overrides, **settings)
    if path == "light" and not r.scene.lights:
        raise SettingsError("animate: path 'light' moves the scene's lights, and it has none (allowed: orbit, dolly)")
    anim = Animation(technique, path)
    steps = _updates(r.scene, path, frames)
    if progress:
        from tqdm import tqdm

        steps = tqdm(steps, desc=f"{technique} {path}", unit="frame", leave=False)
    for k, change in enumerate(steps):
        t0 = time.perf_counter()
        if k:
            r.update(**change)
        frame = r.render()
        image = frame.image  # read back: part of a frame's cost
        anim.seconds.append(time.perf_counter() - t0)
        anim.frames.append(image)
        for stage, run in frame.stages.items():
            counts = anim.stages.setdefault(stage, {"ran": 0, "cached": 0, "skipped": 0})
            counts[run.status] = counts.get(run.status, 0) + 1
    if out is not None:
        save_animation(out, anim.frames, fps, exposure)
    return anim
