"""The public entry points: render a scene with a technique, get a Frame; or keep a
``Renderer`` for animation and interaction, which re-runs only what a change invalidates."""

from __future__ import annotations

from .adaptive import check_budget, check_target, render_auto, render_to_target
from .pipeline import Frame, SettingsError
from .scene import load_scene
from .renderer import Renderer, render_once, technique_class, technique_names  # noqa: F401  (the public API)


def render(scene, technique: str = "reference", device: str | None = None, progress: bool = False,
           overrides: list[str] | dict | None = None, **settings) -> Frame:
    """Render ``scene`` (a Scene, a .toml path, a built-in name or a dict) with ``technique``.

    ``overrides`` changes scene keys by their dotted path, the CLI's ``--set`` spelling:
    ``{"camera.width": 320, "media.0.sigma_t": 2.0}`` or ``["camera.width=320"]``.

    Settings are the technique's (``warpvol.techniques.TECHNIQUES[name].SETTINGS``); an
    unknown name or an out-of-range value raises before anything runs. The image is
    finished: an iterative technique (illumination_network) iterates until it converges
    (a ``Renderer`` runs its per-frame iterations instead).

    ``target_error`` (0..1): the relative RMSE (``metrics.relative_rmse``: RMSE over the
    reference's mean, the same at any exposure) the image may have against the technique's own
    converged answer, every discretisation setting at its limit (its model's omissions are
    ``frame.leaves_out``). The technique's ``Quality`` says how: its knob (raymarch,
    light_shafts and particle_glow steps, rbf_propagation grid, depth_impostors slices,
    illumination_network directions, reference spp) doubles from its start with the settings
    tied to it. At the first level whose error, extrapolated from the last three
    (``remaining_error``), meets the target, one more level is rendered and that level's error
    measured against it (``measured_error``); if that meets the target too, the ladder stops
    there, else it goes on. Then each ``Bias`` setting (light_shafts' block, shadow-map and
    light-pass resolutions, sky directions) is rendered at its
    limit at that level and its bias measured (``bias_error``); the estimate is the ladder's
    error and the biases added in quadrature. A bias above half the target (or one that leaves
    the ladder too little) is taken to its limit and the ladder runs again, up to
    ``MAX_ROUNDS`` times. Where a seed gives independent answers of one quality
    (``Technique.QUALITY_SEED``) each level is the mean of two seeds and their standard error is
    part of the estimate; for the reference, unbiased, it is the whole estimate.
    ``frame.error_estimate`` holds the estimate, ``frame.bias_estimates`` each bias measured,
    ``frame.moved_to_limit`` the settings taken to their limit; above the target at the knob's
    limit, a warning. How well it holds: results/target-error. ``max_seconds`` bounds the search:
    a level (a round of biases, the reference's next sample count) that would not end within it,
    predicted from the last level's time, is not started; the frame is the best found, with its
    estimate, and a warning says it stopped at the budget.

    ``technique="auto"`` (with ``target_error``, against the physical answer, all orders of
    scattering): the fastest technique whose measured error on the scene's family meets it
    (``frame.technique``; ``frame.choice`` says why), else the reference.
    """
    if overrides:
        scene = load_scene(scene, overrides)
    if technique == "auto":
        return render_auto(scene, device, progress, settings)
    if "max_seconds" in settings and "target_error" not in settings:
        raise SettingsError("setting max_seconds bounds a target_error search (allowed: with target_error)")
    if "target_error" in settings:
        target = check_target(settings.pop("target_error"))
        budget = check_budget(settings.pop("max_seconds")) if "max_seconds" in settings else None
        return render_to_target(scene, technique, device, progress, target, settings, budget)
    return render_once(scene, technique, device, progress, **settings)
