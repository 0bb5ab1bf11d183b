"""Ask for an accuracy instead of a setting: raymarch on hazy-sun within 2% of its own converged answer,
then auto within 25% of the physical one (the fastest technique measured to meet it).

    python examples/target_error.py [--size 64x48] [--target 0.02]
"""

import argparse

import warpvol as wv

p = argparse.ArgumentParser()
p.add_argument("--size", default="64x48")
p.add_argument("--target", type=float, default=0.02, help="raymarch's target against its own converged answer")
args = p.parse_args()
w, h = map(int, args.size.split("x"))
size = {"camera.width": w, "camera.height": h}

frame = wv.render("hazy-sun", "raymarch", target_error=args.target, overrides=size)
print(f"raymarch: steps = {frame.settings['steps']}, estimated error {frame.error_estimate:.3g}")
frame = wv.render("fog-box", "auto", target_error=0.25, overrides=size)
print(f"auto: {frame.choice}")
