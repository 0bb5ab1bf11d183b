"""Images before and after a change: every built-in scene with every technique that accepts it,
small and seeded, saved to a folder, then compared with a later save.

    python -m warpvol.bench.same_images --save /tmp/before       # at the commit before
    python -m warpvol.bench.same_images --compare /tmp/before    # after: per image, identical or by how much

A refactoring that moves code leaves every image identical bit for bit; one that reorders float
arithmetic moves pixels by rounding, which ``--compare`` reports as the largest difference
relative to the image's largest value.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import warpvol as wv
from warpvol.scene.procedural import BUILTIN

#: Small renders: seconds for all of them on two CPU cores.
SIZE = ["camera.width=32", "camera.height=24"]
SETTINGS = {"reference": {"spp": 4}, "illumination_network": {"directions": 32}}


def renders(device: str):
    for scene_name in sorted(BUILTIN):
        scene = wv.load_scene(scene_name, SIZE)
        for technique in wv.technique_names():
            seeded = {"seed": 7} if "seed" in wv.technique_class(technique).SETTINGS else {}
            try:
                image = wv.render(scene, technique=technique, device=device, **seeded, **SETTINGS.get(technique, {})).image
            except (wv.SettingsError, wv.SceneError):
                continue  # the technique does not render this scene
            yield f"{scene_name}.{technique}", image


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m warpvol.bench.same_images", description=__doc__.split("\n\n")[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--save", type=Path, help="write each image as NAME.npy into this folder")
    g.add_argument("--compare", type=Path, help="compare each image with NAME.npy in this folder")
    p.add_argument("--device", default="cpu")
    args = p.parse_args(argv)
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
        for name, image in renders(args.device):
            np.save(args.save / f"{name}.npy", image)
            print(f"{name}: saved")
        return 0
    worst, same, total = 0.0, 0, 0
    for name, image in renders(args.device):
        path = args.compare / f"{name}.npy"
        if not path.exists():
            print(f"{name}: no image before")
            continue
        before = np.load(path)
        total += 1
        if np.array_equal(before, image):
            same += 1
            print(f"{name}: identical")
            continue
        rel = float(np.abs(before - image).max() / max(float(np.abs(before).max()), 1e-30))
        worst = max(worst, rel)
        print(f"{name}: max |after - before| / max |before| = {rel:.3g}")
    print(f"{same} of {total} identical; the largest relative difference {worst:.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
