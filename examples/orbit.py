"""A camera orbit around fog-box with light_shafts, written as a GIF.

    python examples/orbit.py [--size 160x120] [--frames 30] [--out orbit.gif]
"""

import argparse

import warpvol as wv

p = argparse.ArgumentParser()
p.add_argument("--size", default="160x120")
p.add_argument("--frames", type=int, default=30)
p.add_argument("--out", default="orbit.gif")
args = p.parse_args()
w, h = map(int, args.size.split("x"))

anim = wv.animate("fog-box", "light_shafts", path="orbit", frames=args.frames, out=args.out,
                  overrides={"camera.width": w, "camera.height": h})
print(anim.summary())
