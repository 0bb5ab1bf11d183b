"""Error measures between an image and a reference (both H x W x 3, linear radiance).

Every accuracy figure in warpvol (``render(target_error=...)``, ``frame.error_estimate``,
``technique="auto"``, ``model_error.json`` and the accuracy sweeps in ``results/``) is
``relative_rmse``: the RMSE over the reference's mean. It is free of exposure: scaling the
image and the reference by any k > 0 leaves it unchanged, so a dim fog box and a bright one
with the same structure of error score the same.

``hdr_flip`` is a second measure, made for rendered images: HDR-FLIP (Andersson et al., "FLIP: A
Difference Evaluator for Alternating Images", HPG 2020, and its HDR extension, 2021) tone-maps
both images at the exposures that span the reference's range and scores the error a viewer sees
at the worst of them, per pixel in [0, 1]. RMSE / mean weighs every pixel's error in radiance, so
a light's singular core, a handful of pixels, can decide it; ꟻLIP weighs what is visible, so a
core that clips to white in both images costs nothing, and a wrong shadow on a dim wall costs
what it looks like. Trust RMSE / mean for energy (the mean's error, a bias in radiance), ꟻLIP for
how an image looks; the accuracy pages show both. ``target_error`` stays on RMSE / mean: its
estimates extrapolate a quantity that falls as a power of the step, which ꟻLIP's clipped,
perceptual scale does not.
"""

import numpy as np


def error_scale(reference: np.ndarray) -> float:
    """The reference's mean value over pixels and channels: what ``relative_rmse`` divides by."""
    return float(np.mean(np.abs(np.asarray(reference, np.float64))))


def relative_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """sqrt(mean((x - r)^2)) / mean(r): the RMSE in units of the reference's mean radiance.

    Scale-free: relative_rmse(k x, k r) = relative_rmse(x, r) for every k > 0. It is the
    normalised RMSE (NRMSE, the coefficient of variation of the error). The per-pixel relMSE
    of Rousselle, Knaus and Zwicker ("Adaptive sampling and reconstruction using greedy
    error minimization", SIGGRAPH Asia 2011), mean((x - r)^2 / (r^2 + eps)), is free of
    exposure only if eps is taken relative to the image's scale, and even then it weighs a
    dim pixel's error up to 1/eps times a bright one's, so a few dark pixels decide the
    score. Dividing by the mean weighs every pixel's error in the same radiance units, as a
    viewer at one exposure sees it, and an image's standard error is the same quantity for
    the mean of its noise. A black reference: 0 for a black image, else inf."""
    x, r = np.asarray(image, np.float64), np.asarray(reference, np.float64)
    err = rmse(x, r)
    scale = error_scale(r)
    if scale > 0.0:
        return err / scale
    return 0.0 if err == 0.0 else float("inf")


def rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """sqrt(mean((x - r)^2)), in the images' units; ``reference`` may be a scalar (0: the RMS)."""
    return float(np.sqrt(np.mean((np.asarray(image, np.float64) - np.asarray(reference, np.float64)) ** 2)))


def hdr_flip(image: np.ndarray, reference: np.ndarray, error_map: bool = False):
    """The mean HDR-FLIP error of ``image`` against ``reference`` (both H x W x 3 linear
    radiance, negative values taken as 0): 0 for identical images, at most 1. Free of exposure
    (the exposures are chosen from the reference's range). With ``error_map``, also the per-pixel
    error in false colour (H x W x 3 in [0, 1], magma), for a PNG. Needs the flip-evaluator
    package (the ``bench`` extra: ``pip install 'warpvol[bench]'``)."""
    try:
        import flip_evaluator
    except ImportError:
        raise ImportError("hdr_flip needs the flip-evaluator package: pip install 'warpvol[bench]'") from None
    ref = np.clip(np.nan_to_num(np.asarray(reference, np.float32)), 0.0, None)
    img = np.clip(np.nan_to_num(np.asarray(image, np.float32)), 0.0, None)
    fmap, mean, _ = flip_evaluator.evaluate(ref, img, "HDR", applyMagma=error_map)
    return (float(mean), np.asarray(fmap, np.float32)) if error_map else float(mean)
