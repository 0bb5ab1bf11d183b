"""A live view: a window whose image is re-rendered through a ``Renderer`` as the mouse drags
the camera round its target, at a resolution that keeps it interactive.

    python -m warpvol live fog-box --technique light_shafts
    python -m warpvol live fog-box --frames 60 --screenshot live.png     # off screen

Dragging with the left button orbits the camera (only the camera's stages re-run: the title
line says which ran and the frames per second); ``t`` switches to the next technique that takes
the scene, ``r`` shows the reference (all orders) accumulating sample by sample where the
technique's image was, and back. ``LiveView`` is the loop without the window: tests and
scripts drive it directly.
"""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np

import warpvol as wv
from warpvol.animation import rotate
from warpvol.image import tonemap

DEGREES_PER_PIXEL = 0.5


#: The title's font (size 10) in pixels: a character's width, at most, and a line's height.
CHAR_PX, LINE_PX = 8, 16


def fitted(text: str, width_px: int) -> list[str]:
    """``text`` wrapped at its commas and spaces into lines no wider than ``width_px`` at
    CHAR_PX a character (one line ran off the window's right edge: "...surface, mar")."""
    import textwrap

    return textwrap.wrap(text, width=max(20, width_px // CHAR_PX)) or [""]


class LiveView:
    """The live loop: ``orbit`` turns the camera, ``frame`` renders (the Renderer re-runs what the
    change feeds), ``fps`` over the last 30 frames, ``switch`` the next technique, ``reference``
    on or off (then each frame adds one sample a pixel to a running mean)."""

    def __init__(self, scene, technique: str = "light_shafts", device: str | None = None, size=(160, 120),
                 **settings):
        w, h = size
        self.scene = wv.load_scene(scene, {"camera.width": int(w), "camera.height": int(h)}) \
            if not isinstance(scene, wv.Scene) else scene
        self.device, self.settings = device, settings
        self.techniques = [n for n in wv.technique_names() if n != "reference" and self._takes(n)]
        if technique not in self.techniques:
            raise wv.SettingsError(f"live: {technique} does not take {self.scene.name} (allowed: "
                                   f"{', '.join(self.techniques)})")
        self.technique = technique
        self.renderer = wv.Renderer(self.scene, technique, device, **settings)
        self.times: deque = deque(maxlen=30)
        self.ran: list[str] = []
        self.show_reference = False
        self._ref_sum, self._ref_n = None, 0

    def _takes(self, name: str) -> bool:
        try:
            wv.Renderer(self.scene, name, self.device)
            return True
        except (wv.SettingsError, ValueError):
            return False

    def orbit(self, yaw_deg: float, pitch_deg: float = 0.0) -> None:
        """Turn the camera about its target: yaw about its up, pitch about its right."""
        cam = self.renderer.scene.camera
        o, t, up = (np.asarray(v, float) for v in (cam.origin, cam.target, cam.up))
        up = up / np.linalg.norm(up)
        v = rotate(o - t, up, math.radians(yaw_deg))
        right = np.cross(v, up)
        if pitch_deg and np.linalg.norm(right) > 0:
            turned = rotate(v, right / np.linalg.norm(right), math.radians(pitch_deg))
            if abs(np.dot(turned / np.linalg.norm(turned), up)) < 0.98:  # not over the pole
                v = turned
        self.renderer.update(camera={"origin": (t + v).tolist()})
        self._ref_sum, self._ref_n = None, 0

    def switch(self) -> str:
        """The next technique that takes the scene, at the current camera."""
        k = (self.techniques.index(self.technique) + 1) % len(self.techniques)
        self.technique = self.techniques[k]
        self.renderer = wv.Renderer(self.renderer.scene, self.technique, self.device)
        return self.technique

    def toggle_reference(self) -> bool:
        self.show_reference = not self.show_reference
        self._ref_sum, self._ref_n = None, 0
        return self.show_reference

    def frame(self) -> np.ndarray:
        """Render one frame (the technique's, or the reference's running mean) and time it."""
        t0 = time.perf_counter()
        if self.show_reference:
            img = wv.render(self.renderer.scene, "reference", self.device, spp=1, seed=self._ref_n + 1,
                            pixel_area=0).image.astype(np.float64)
            self._ref_sum = img if self._ref_sum is None else self._ref_sum + img
            self._ref_n += 1
            image = (self._ref_sum / self._ref_n).astype(np.float32)
            self.ran = [f"reference, {self._ref_n} spp"]
        else:
            frame = self.renderer.render()
            image = frame.image
            self.ran = [s for s, run in frame.stages.items() if run.status == "ran"]
        self.times.append(time.perf_counter() - t0)
        return image

    @property
    def fps(self) -> float:
        return len(self.times) / max(sum(self.times), 1e-9) if self.times else 0.0

    def title(self) -> str:
        what = "reference (r: back)" if self.show_reference else f"{self.technique} (t: next, r: reference)"
        return f"{what}  {self.fps:.1f} FPS  ran: {', '.join(self.ran) or 'nothing'}"

    def show(self, off_screen: bool = False, frames: int = 0, screenshot: str | None = None,
             window_size=(800, 600)) -> None:
        """The window (pyvista): the image on a quad filling it, the title line over it; with
        ``frames`` > 0 it orbits once round in that many frames by itself (off screen: then
        saves ``screenshot`` and closes)."""
        import pyvista as pv
        from vtkmodules.vtkInteractionStyle import vtkInteractorStyleUser

        cam = self.renderer.scene.camera
        w, h = cam.width, cam.height
        plotter = pv.Plotter(off_screen=off_screen, window_size=window_size)
        quad = pv.Plane(i_size=w, j_size=h, i_resolution=1, j_resolution=1)
        actor = plotter.add_mesh(quad, texture=pv.numpy_to_texture(np.zeros((h, w, 3), np.uint8)), lighting=False)
        plotter.set_background("black")
        plotter.camera_position = "xy"
        plotter.enable_parallel_projection()
        plotter.reset_camera(bounds=(-w / 2, w / 2, -h / 2, h / 2, 0, 0))
        plotter.camera.parallel_scale = 0.5 * h

        def redraw():
            image = self.frame()
            actor.texture = pv.numpy_to_texture(np.ascontiguousarray(tonemap(image)))
            lines = fitted(self.title(), window_size[0] - 16)
            plotter.add_text("\n".join(lines), position=(8, window_size[1] - 26 - LINE_PX * (len(lines) - 1)),
                             font_size=10, color="white", name="title")
            plotter.render()

        if frames > 0 or off_screen:
            plotter.show(auto_close=False, interactive=False) if not off_screen else None
            for _ in range(max(frames, 1)):
                self.orbit(360.0 / max(frames, 1))
                redraw()
            if screenshot:
                plotter.screenshot(screenshot)
            plotter.close()
            return

        state = {"down": None}
        iren = plotter.iren.interactor
        iren.SetInteractorStyle(vtkInteractorStyleUser())  # the drag is ours, not VTK's camera's

        def press(obj, _):
            state["down"] = obj.GetEventPosition()

        def release(obj, _):
            state["down"] = None

        def move(obj, _):
            if state["down"] is not None:
                x, y = obj.GetEventPosition()
                x0, y0 = state["down"]
                state["down"] = (x, y)
                self.orbit(-(x - x0) * DEGREES_PER_PIXEL, (y - y0) * DEGREES_PER_PIXEL)
                redraw()

        def key(obj, _):
            k = obj.GetKeySym()
            if k == "t":
                self.switch()
            elif k == "r":
                self.toggle_reference()
            else:
                return
            redraw()

        iren.AddObserver("LeftButtonPressEvent", press)
        iren.AddObserver("LeftButtonReleaseEvent", release)
        iren.AddObserver("MouseMoveEvent", move)
        iren.AddObserver("KeyPressEvent", key)
        redraw()
        plotter.show()
