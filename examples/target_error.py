"""Ask for an accuracy instead of a setting: raymarch within 2% of its own converged answer,
then auto within 25% of the physical one (the fastest technique measured to meet it).

    python examples/target_error.py [--size 64x48]
"""

import argparse

import warpvol as wv

p = argparse.ArgumentParser()
p.add_argument("--size", default="64x48")
args = p.parse_args()
w, h = map(int, args.size.split("x"))
size = {"camera.width": w, "camera.height": h}

frame = wv.render("point-in-fog", "raymarch", target_error=0.02, overrides=size)
print(f"raymarch: steps = {frame.settings['steps']}, estimated error {frame.error_estimate:.3g}")
frame = wv.render("fog-box", "auto", target_error=0.25, overrides=size)
print(f"auto: {frame.choice}")
