"""What a render returns: the image and what it cost (``Frame``)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..image import png_bytes, tonemap
from .technique import StageRun


class Frame:
    """A rendered image (H x W x 3 float32, linear RGB, row 0 at the top) and what it cost.

    ``stages`` maps each stage to its ``StageRun`` (status and ms); ``timings`` is the
    {stage: seconds} view of the same data. The image is copied off the device the first
    time ``image`` is read, so timing a frame does not time the read-back.
    """

    #: How an entry of ``leaves_out`` starts when the model approximates that physics rather than omits it.
    APPROXIMATED = "approximated, not left out: "

    def __init__(self, output, shape: tuple[int, int], technique: str, device: str, settings: dict,
                 stages: dict[str, StageRun], leaves_out: list[str] | None = None):
        self.leaves_out = list(leaves_out or [])  # what the technique's model leaves out of the physics
        self.error_estimate: float | None = None  # render(target_error=...): the image's estimated error
        self.bias_estimates: dict[str, float] = {}  # render(target_error=...): each Bias setting's measured part
        self.moved_to_limit: dict = {}  # render(target_error=...): the Bias settings it took to their limits
        self.choice: str | None = None  # render(technique="auto"): what was chosen and why
        self._output = output
        self._image = None
        self.shape = shape
        self.technique = technique
        self.device = device
        self.settings = settings
        self.stages = stages

    @property
    def approximates(self) -> list[str]:
        """The entries of ``leaves_out`` the model approximates (after the ``APPROXIMATED`` mark)."""
        return [x[len(self.APPROXIMATED):] for x in self.leaves_out if x.startswith(self.APPROXIMATED)]

    @property
    def omits(self) -> list[str]:
        """The entries of ``leaves_out`` the model has no part of."""
        return [x for x in self.leaves_out if not x.startswith(self.APPROXIMATED)]

    def _repr_png_(self) -> bytes:
        """The image as a PNG (sRGB, exposure 0): what a notebook (Jupyter, IPython) shows for a Frame."""
        return png_bytes(tonemap(self.image))

    @property
    def image(self) -> np.ndarray:
        if self._image is None:
            data = self._output.numpy() if isinstance(self._output, wp.array) else np.asarray(self._output)
            self._image = data.astype(np.float32, copy=False).reshape(*self.shape, 3)
            self._output = None
        return self._image

    @property
    def timings(self) -> dict[str, float]:
        return {name: run.ms / 1000.0 for name, run in self.stages.items()}

    def __repr__(self) -> str:
        runs = ", ".join(f"{n}={r.status}" for n, r in self.stages.items())
        return f"Frame({self.technique} on {self.device}, {self.shape[1]}x{self.shape[0]}; {runs})"
