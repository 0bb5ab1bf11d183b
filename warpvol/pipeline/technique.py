"""The base of every technique (``Technique``), its stages (``Stage``) and what a stage's run
came to (``StageRun``)."""

from __future__ import annotations

from typing import Callable, NamedTuple

from .settings import Quality, Setting

PARTS = ("medium", "lights", "camera", "surfaces", "background")


def has_sky(scene) -> bool:
    """Whether the scene's background lights its media: a non-black sky and some medium."""
    return any(c > 0.0 for c in scene.background) and bool(scene.media)


class Stage(NamedTuple):
    """One pass of a technique.

    ``run`` computes the stage's outputs and keeps them on the technique. ``reads`` names
    scene parts (``PARTS``), ``settings`` the settings it reads, ``after`` the earlier
    stages whose outputs it uses. ``needed=False`` when the scene does not call for it.
    ``settled=False`` makes it run even with unchanged inputs: an iterative solver whose
    state has not converged yet. ``run`` may return False: it ran and found its outputs as
    they were (say, a block template that an animation moved but did not change), so the
    stages after it stay cached.
    """

    name: str
    run: Callable[[], None]
    reads: tuple[str, ...] = ()
    settings: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    needed: bool = True
    settled: bool = True


class StageRun(NamedTuple):
    status: str  # "ran" | "cached" | "skipped"
    ms: float  # device-synchronised wall time; 0 unless it ran


class Technique:
    """Base of every technique: the scene, device and settings, and the stages of a frame.

    Subclasses set ``NAME`` and ``SETTINGS``, keep their buffers as attributes, and define
    ``stages()`` (the graph, in order, re-read every frame so ``needed`` follows the
    scene) and ``output()`` (the last frame's image: H*W vec3 on the device, or numpy).
    """

    NAME = ""
    SETTINGS: dict[str, Setting] = {}

    # The technique's own facts, which the suite, the census and the campaign read from
    # ``TECHNIQUES`` (tests/test_registry.py fails where one is missing):
    #: built-in scenes it is audited on (every stage run twice, tests/test_pipeline.py)
    EXAMPLES: tuple[str, ...] = ()
    #: settings for a frame of a few milliseconds on a 16 x 12 scene (tests/test_fuzz.py)
    TINY: dict = {}
    #: the census frame (bench/campaign.py): a built-in scene and settings, tens of ms on a GPU
    CENSUS: tuple[str, dict] = ("", {})

    def __init__(self, scene, device: str, settings: dict, progress: bool = False):
        self.scene = scene
        self.device = device
        self.settings = settings
        self.progress = progress
        self.check_settings(settings)

    def check_settings(self, settings: dict) -> None:
        """Raise ``SettingsError`` for combinations the ranges alone do not exclude."""

    def stages(self) -> list[Stage]:
        raise NotImplementedError

    def output(self):
        raise NotImplementedError

    #: What the technique's model leaves out of the physical answer (all orders of scattering
    #: of every light, the sky included), e.g. "multiple scattering".
    LEAVES_OUT: tuple[str, ...] = ()

    def leaves_out(self) -> list[str]:
        """``LEAVES_OUT``, and the sky's light where the scene has a sky the technique does not
        gather (``sky_samples`` = 0, or no such setting) and no multiple-scattering lattice
        approximates (``multiple_scattering`` = 0)."""
        out = list(self.LEAVES_OUT)
        # with the lattice on, it carries the sky over the media and lights the surfaces beyond them
        if has_sky(self.scene) and not self.gathers_sky and not self.settings.get("multiple_scattering", 0):
            out.append("the sky's light (the background) scattered in the media or reflected by surfaces")
        return out

    def pixel_work(self, light_samples: float, steps: float = 0.0) -> float:
        """A pixel's work in units of a simple pixel (``device.launch`` splits a CPU launch by it):
        ``light_samples`` for each of the scene's lights (one where it has none), and ``steps``
        density samples of its own."""
        return light_samples * max(1, len(self.scene.lights)) + steps

    #: True: the technique gathers the sky's light whatever its settings (e.g. by following paths).
    GATHERS_SKY: bool = False

    @property
    def gathers_sky(self) -> bool:
        """Whether the technique gathers the sky's light itself: always (``GATHERS_SKY``) or with
        ``sky_samples`` > 0 (else the multiple-scattering lattice carries it, where it is on)."""
        return self.GATHERS_SKY is True or self.settings.get("sky_samples", 0) > 0

    #: What ``render(target_error=...)`` raises and measures (``Quality``); None: target_error is
    #: not supported.
    QUALITY: Quality | None = None

    #: A seed setting whose values give independent answers of the same quality (Monte Carlo
    #: samples, turned direction sets): ``target_error`` then estimates the error from the spread
    #: of two seeds at one level instead of from successive levels. None: levels.
    QUALITY_SEED: str | None = None

    #: Settings ``target_error`` holds at these values (unless given) while it raises the knob.
    QUALITY_HOLD: dict = {}

    #: ``Renderer(one_shot=True)`` (as ``warpvol.render`` makes it): the frame is the only one, so
    #: an iterative technique runs to convergence instead of its per-frame iterations (by
    #: default a ``Renderer`` keeps the paper's loop).
    one_shot: bool = False

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """Intermediate arrays of the last frame, as numpy, for looking inside (``viz``).

        ``for_view`` adds what a picture needs beyond the frame's own arrays, however costly
        (rbf_propagation's marched optical depth); ``resolution`` is the side of arrays sampled
        only to be looked at (light_shafts' lit slice). Every technique takes both."""
        return {}

    def diagnostics(self) -> dict:
        """Named figures of the last frame a benchmark reports beside the image (e.g. the
        window illumination_network used), as plain numbers or numpy arrays; each technique
        documents its own. The public way for bench/ and viz/ to read a technique's state."""
        return {}
