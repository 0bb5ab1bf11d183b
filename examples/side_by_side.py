"""Every real-time technique that takes a scene, beside the reference (all orders of
scattering), with each one's time and relative RMSE against it; one PNG per technique.

    python examples/side_by_side.py [SCENE] [--size 96x72] [--spp 256] [--out side/]
"""

import argparse
import os
import time

import warpvol as wv

p = argparse.ArgumentParser()
p.add_argument("scene", nargs="?", default="smoke-grid")
p.add_argument("--size", default="96x72")
p.add_argument("--spp", type=int, default=256)
p.add_argument("--out", default="side")
args = p.parse_args()
w, h = map(int, args.size.split("x"))
scene = wv.load_scene(args.scene, {"camera.width": w, "camera.height": h})
os.makedirs(args.out, exist_ok=True)

truth = wv.render(scene, "reference", spp=args.spp, pixel_area=0)  # pixel centres, as the marchers sample
wv.save_image(os.path.join(args.out, "reference.png"), truth.image)
for name in wv.technique_names():
    if name == "reference":
        continue
    try:
        r = wv.Renderer(scene, name)
    except (wv.SettingsError, ValueError) as why:  # a technique that does not model this medium
        print(f"{name:22s} -- {str(why).splitlines()[0][:70]}")
        continue
    r.render()  # the first frame compiles and uploads
    r.touch()
    t0 = time.perf_counter()
    frame = r.render()
    image = frame.image
    ms = 1000.0 * (time.perf_counter() - t0)
    wv.save_image(os.path.join(args.out, f"{name}.png"), image)
    print(f"{name:22s} {ms:8.1f} ms  relative RMSE {wv.relative_rmse(image, truth.image):.3f}")
