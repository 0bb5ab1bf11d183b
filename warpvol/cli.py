"""Command line: ``python -m warpvol render | bench | view | scenes``.

    python -m warpvol render SCENE --technique NAME --out OUT.exr [--out OUT.png] [--device cpu|cuda]
                             [--spp N] [--set key=value ...] [--timings] [--exposure EV]
                             [--workers N | --scheduler tcp://HOST:8786]     # the reference, on Dask
    python -m warpvol bench --list | SWEEP [--quick] [--device ...] [--out results] | report [SWEEP ...] [--overview | --stale]
                            [--workers N | --scheduler tcp://HOST:8786]      # the points, on Dask
    python -m warpvol view SCENE [--screenshot FILE.png] [--technique NAME] [--set key=value ...]
    python -m warpvol scenes

Each command prints its own lines and nothing else; ``--verbose`` also shows Warp's (its
banner, module loads, a missing CUDA driver) and VTK's warnings.

``--workers N`` starts a Dask ``LocalCluster`` of N worker processes here, ``--scheduler``
joins a running cluster (``warpvol.cluster``); without either, everything runs in this process.
Without ``--device``, each worker renders on the device it picks itself.

``--set`` takes a technique setting (``--set steps=128``) or a scene key in dotted form
(``--set camera.width=64``, ``--set media.0.sigma_t=2``). Bad input exits with status 2
and one line on stderr.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings


class _Parser(argparse.ArgumentParser):
    """argparse whose errors are one line, like every other bad input: ``warpvol: error: ...``, status 2."""

    def error(self, message):
        self.exit(2, f"warpvol: error: {message} (see {self.prog} --help)\n")


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer (allowed: a whole number, e.g. 64)") from None


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number (allowed: a finite number, e.g. -1.5)")
    return value


def _stem(scene: str) -> str:
    """A scene argument's name for default output files: a built-in name, or a file's stem."""
    return os.path.splitext(os.path.basename(scene))[0]


def _quiet_vtk(args) -> None:
    """Silence VTK's own warnings (e.g. "bad X server connection" off screen) unless --verbose."""
    if not args.verbose:
        from vtkmodules.vtkCommonCore import vtkObject

        vtkObject.GlobalWarningDisplayOff()


DEVICE_HELP = "cpu | cuda | cuda:N (default: $WARPVOL_DEVICE, else CUDA if present)"
SCENE_TOP_LEVEL = ("name", "background", "camera", "lights", "media", "surfaces")


def _parse_set(values: list[str], technique: str) -> tuple[dict, list[str]]:
    """Split ``--set`` items into the technique's settings and scene overrides; a plain key that
    belongs to another technique is an error here, not an unknown scene key later."""
    from warpvol.pipeline import SettingsError
    from warpvol.scene.load import tomllib
    from warpvol.names import closest
    from warpvol.techniques import TECHNIQUES

    spec = TECHNIQUES[technique].SETTINGS if technique != "auto" else {}
    settings, overrides = {}, []
    for item in values:
        key, _, value = item.partition("=")
        if key in spec or key in ("target_error", "max_seconds", "frame_ms"):  # warpvol.render's own
            try:
                settings[key] = tomllib.loads(f"v = {value}")["v"]
            except tomllib.TOMLDecodeError:
                settings[key] = value
            continue
        owners = [name for name, cls in TECHNIQUES.items() if key in cls.SETTINGS]
        typo = closest(key, spec) if "." not in key and key not in SCENE_TOP_LEVEL else None
        if typo and not owners:
            raise SettingsError(f"--set {item}: {key} is not a setting of {technique}; did you mean {typo}? "
                                f"(allowed for {technique}: {', '.join(sorted(spec))}; or a scene key such as "
                                f"camera.width)")
        if owners:
            raise SettingsError(f"--set {item}: {key} is a setting of {' and '.join(owners)}, not of {technique} "
                                f"(allowed for {technique}: {', '.join(sorted(spec)) or 'no settings'}; "
                                f"or a scene key such as camera.width)")
        overrides.append(item)
    return settings, overrides


def cmd_render(args) -> int:
    import warpvol as wv
    from warpvol.api import technique_class
    from warpvol.image import check_output_path
    from warpvol.pipeline import SettingsError

    if not args.out:
        args.out = [f"{_stem(args.scene)}.{args.technique}.png"]
    for out in args.out:  # before anything is loaded or rendered
        check_output_path(out)
    spec = technique_class(args.technique).SETTINGS if args.technique != "auto" else {}
    settings, overrides = _parse_set(args.set or [], args.technique)
    if args.spp is not None:
        if "spp" not in spec:
            raise SettingsError(f"{args.technique}: --spp does not apply (allowed: with --technique reference)")
        settings["spp"] = args.spp
    scene = wv.load_scene(args.scene, overrides)
    t0 = time.perf_counter()
    if _on_cluster(args):
        cluster = _cluster()
        if args.technique != "reference":
            raise SettingsError(f"{args.technique}: --workers and --scheduler split the reference's samples over a "
                                "cluster (allowed: --technique reference)")
        if "target_error" in settings:
            raise SettingsError("target_error is not supported on a cluster (allowed: --spp N, or --set spp=N)")
        with cluster.connect(args.workers, args.scheduler) as client:
            frame = cluster.render_reference(client, scene, args.device, **settings)
    else:
        frame = wv.render(scene, technique=args.technique, device=args.device, progress=True, **settings)
    for out in args.out:
        wv.save_image(out, frame.image, exposure=args.exposure)
    wall = time.perf_counter() - t0
    chosen = ""
    if frame.error_estimate is not None:
        knob = technique_class(frame.technique).QUALITY.knob
        chosen = ", ".join(f"{k} = {frame.settings[k]}" for k in [knob, *frame.moved_to_limit])
        chosen = f", {chosen}, estimated error {frame.error_estimate:.3g}"
        if frame.bias_estimates:  # the ladder's lines gave the knob's part; the rest is the biases'
            chosen += " (biases: " + ", ".join(f"{k} {e:.3g}" for k, e in frame.bias_estimates.items()) + ")"
    name = f"auto -> {frame.technique}" if args.technique == "auto" else frame.technique
    print(f"{scene.name}: {name} on {frame.device}, {scene.camera.width}x{scene.camera.height}{chosen}, "
          f"{wall:.2f} s -> {', '.join(args.out)}")
    if frame.choice:
        print(f"  auto: {frame.choice}")
    if args.timings:
        for stage, run in frame.stages.items():
            print(f"  {stage:<14} {run.status:<8} {run.ms:10.2f} ms")
    return 0


def cmd_animate(args) -> int:
    import warpvol as wv
    from warpvol.animation import check_output
    from warpvol.pipeline import SettingsError

    paths = [(p, n) for p, n in (("orbit", args.orbit), ("dolly", args.dolly), ("light", args.light)) if n]
    if len(paths) != 1:
        raise SettingsError("animate: give one of --orbit N, --dolly N, --light N (allowed: exactly one path)")
    path, frames = paths[0]
    if not args.out:
        args.out = f"{_stem(args.scene)}.{args.technique}.{path}.gif"
    check_output(args.out)
    settings, overrides = _parse_set(args.set or [], args.technique)
    scene = wv.load_scene(args.scene, overrides)
    anim = wv.animate(scene, args.technique, path=path, frames=frames, device=args.device, progress=True,
                      out=args.out, fps=args.fps, exposure=args.exposure, **settings)
    first, *stages = anim.summary().splitlines()
    print(f"{scene.name}: {args.technique}, {scene.camera.width}x{scene.camera.height}, {first} -> {args.out}")
    print("\n".join(stages))
    return 0


def _on_cluster(args) -> bool:
    return args.workers is not None or args.scheduler is not None


def _cluster():
    """warpvol.cluster, or a one-line error where Dask is not installed."""
    try:
        from warpvol import cluster
    except ModuleNotFoundError as exc:
        if exc.name != "distributed":
            raise
        raise ValueError("--workers and --scheduler run on Dask, which is not installed "
                         "(fix: pip install 'warpvol[dask]')") from None
    return cluster


def cmd_bench(args) -> int:
    import os

    from warpvol.bench.harness import device_slug, run_sweep
    from warpvol.bench.report import write_report
    from warpvol.bench.sweeps import SWEEPS

    from warpvol import device as dev

    if args.list or not args.sweep:
        for name, sweep in SWEEPS.items():
            print(f"{name:<38} {sweep.technique:<21} {sweep.doc}")
        return 0
    if args.sweep[0] == "report" and args.overview:
        from warpvol.bench.overview import write

        if args.sweep[1:]:
            raise ValueError("bench report --overview writes results/README.md from every page; name no sweep")
        print(f"overview: {write(args.out)}")
        return 0
    if args.sweep[0] == "report" and args.stale:
        from warpvol.bench.fingerprint import stale

        if args.sweep[1:]:
            raise ValueError("bench report --stale checks every page; name no sweep")
        for page, status in stale(args.out).items():
            print(f"{page}: {status['status']} ({status['why']})")
        print(f"stale: {os.path.join(args.out, 'stale.json')}; the overview reads it (bench report --overview)")
        return 0
    if args.overview or args.stale:
        raise ValueError("--overview and --stale go with `bench report` (python -m warpvol bench report --overview)")
    if args.sweep[0] == "report":
        names = args.sweep[1:] or [n for n in SWEEPS if os.path.isdir(os.path.join(args.out, n))]
        for name in names:
            if name not in SWEEPS:
                raise ValueError(f"unknown sweep {name!r} (allowed: {', '.join(SWEEPS)})")
            path = write_report(args.out, name)
            print(f"{name}: {path or 'no results yet'}")
        return 0
    for name in args.sweep:
        if name not in SWEEPS:
            raise ValueError(f"unknown sweep {name!r} (allowed: {', '.join(SWEEPS)}; see --list)")
    if not _on_cluster(args):
        device = dev.pick(args.device)
        for name in args.sweep:
            path = run_sweep(SWEEPS[name], device, args.out, quick=args.quick)
            print(f"{name}: rows in {path}; report in {write_report(args.out, name)}")
        return 0
    cluster = _cluster()
    where = f" --workers {args.workers}" if args.workers is not None else f" --scheduler {args.scheduler}"
    with cluster.connect(args.workers, args.scheduler) as client:
        # one file for the cluster's rows: named by its workers' device when they share one
        slugs = set(client.run(device_slug, args.device).values())
        slug = slugs.pop() if len(slugs) == 1 else "mixed"
        for name in args.sweep:
            command = (f"python -m warpvol bench {name}{' --quick' if args.quick else ''}"
                       f"{f' --device {args.device}' if args.device else ''}{where}")
            path = run_sweep(SWEEPS[name], args.device, args.out, quick=args.quick,
                             executor=client.get_executor(pure=False), command=command, slug=slug)
            print(f"{name}: rows in {path}; report in {write_report(args.out, name)}")
    return 0


def _needs_viz(command: str, on_screen: bool) -> None:
    """One line, exit 2, instead of a traceback or a silent exit: pyvista is not installed, or a
    window is asked for where there is no display to open it on (Linux without $DISPLAY or
    $WAYLAND_DISPLAY)."""
    import importlib.util
    import os

    if importlib.util.find_spec("pyvista") is None:
        raise ValueError(f"{command} needs pyvista, which is not installed (fix: pip install 'warpvol[viz]')")
    if on_screen and sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                                or os.environ.get("WAYLAND_DISPLAY")):
        raise ValueError(f"{command}: no display to open a window on ($DISPLAY is not set; fix: --screenshot FILE.png "
                         "renders off screen)")


def cmd_view(args) -> int:
    _needs_viz("view", on_screen=args.screenshot is None)
    import warpvol as wv
    from warpvol.viz import scene_plotter, technique_actors

    _quiet_vtk(args)
    settings, overrides = _parse_set(args.set or [], args.technique) if args.technique else ({}, args.set or [])
    scene = wv.load_scene(args.scene, overrides)
    plotter = scene_plotter(scene, off_screen=args.screenshot is not None)
    if args.technique:
        renderer = wv.Renderer(scene, technique=args.technique, device=args.device, **settings)
        renderer.render()
        technique_actors(plotter, args.technique, renderer.arrays(for_view=True))
    if args.screenshot:
        plotter.screenshot(args.screenshot)
        plotter.close()
        print(f"{scene.name}: view -> {args.screenshot}")
    else:
        plotter.show()
    return 0


def cmd_live(args) -> int:
    _needs_viz("live", on_screen=args.screenshot is None)
    from warpvol.viz.live import LiveView

    _quiet_vtk(args)
    settings, overrides = _parse_set(args.set or [], args.technique)
    import warpvol as wv

    w, h = (int(x) for x in args.size.lower().split("x"))
    scene = wv.load_scene(args.scene, [*overrides, f"camera.width={w}", f"camera.height={h}"])
    live = LiveView(scene, args.technique, args.device, **settings)
    off = args.screenshot is not None
    live.show(off_screen=off, frames=args.frames, screenshot=args.screenshot)
    if off or args.frames:
        print(f"{scene.name}: live {live.technique}, {w}x{h}, {len(live.times)} of the last frames at "
              f"{live.fps:.1f} FPS (camera stages: {', '.join(live.ran)})"
              + (f" -> {args.screenshot}" if off else ""))
    return 0


def cmd_demo(args) -> int:
    """A real-time technique and the reference side by side, each with its time and error."""
    import numpy as np

    import warpvol as wv
    from warpvol.image import check_output_path, text_mask

    check_output_path(args.out)
    scene = wv.load_scene(args.scene, args.set or [])
    cached = _kernel_cache_entries()
    frames = []
    for technique, settings in ((args.technique, {}), ("reference", {"target_error": 0.05})):
        t0 = time.perf_counter()  # the real-time technique at its defaults; the reference to 5% noise
        frame = wv.render(scene, technique=technique, device=args.device, **settings)
        frames.append((frame, time.perf_counter() - t0))
    (fast, fast_s), (ref, ref_s) = frames
    # the real-time image against the reference, the reference's own noise taken out in quadrature
    error = float(np.sqrt(max(wv.relative_rmse(fast.image, ref.image) ** 2 - ref.error_estimate**2, 0.0)))
    lum = ref.image @ np.array([0.2126, 0.7152, 0.0722])
    exposure = float(-np.log2(max(np.percentile(lum, 99.5), 1e-30)))  # the reference's 99.5th percentile to white
    # each half captioned under it (technique, time, error), the ink white at this exposure
    w = fast.image.shape[1]
    scale = max(1, w // 160)
    halves = [np.concatenate([img, np.repeat(text_mask(lines, w, scale)[:, :, None], 3, axis=2) * 2.0**-exposure])
              for img, lines in ((fast.image, [fast.technique, f"{fast_s:.2f} s  err {error:.2f}"]),
                                 (ref.image, ["reference", f"{ref_s:.1f} s  noise {ref.error_estimate:.2f}"]))]
    gap = np.zeros((halves[0].shape[0], 4, 3), np.float32)
    wv.save_image(args.out, np.concatenate([halves[0], gap, halves[1]], axis=1), exposure=exposure)
    compiled = _kernel_cache_entries() - cached
    print(f"{scene.name}: {scene.camera.width}x{scene.camera.height} on {fast.device}"
          + (f" (this run compiled {len(compiled)} kernel modules; later runs reuse them)" if compiled else ""))
    print(f"  left:  {fast.technique:<10} {fast_s:6.2f} s  error {error:.3g} against the reference (its defaults"
          + "".join(f"; approximates {x}" for x in fast.approximates)
          + f"; leaves out: {', '.join(fast.omits) or 'nothing'})")
    print(f"  right: reference  {ref_s:6.2f} s  its own noise {ref.error_estimate:.3g} ({ref.settings['spp']} spp, "
          "all orders of scattering)")
    print(f"  -> {args.out} (exposure {exposure:+.2f} stops)")
    return 0


def _kernel_cache_entries() -> set:
    """The modules in Warp's kernel cache (what a run that compiles adds to)."""
    import os

    import warp as wp

    from warpvol import device

    device.init()  # Warp, quietly: sets the cache's folder
    folder = wp.config.kernel_cache_dir
    return set(os.listdir(folder)) if folder and os.path.isdir(folder) else set()


def cmd_docs(args) -> int:
    from pathlib import Path

    from warpvol.docs import write

    root = Path(args.root)
    if not (root / "docs").is_dir() or not (root / "README.md").exists():
        raise ValueError(f"{root}: not a warpvol checkout (allowed: --root the folder with README.md and docs/)")
    stale = write(root, check=args.check)
    for path in stale:
        print(f"{path}: {'out of date' if args.check else 'written'}")
    return 1 if args.check and stale else 0


def _description(make) -> str:
    """A built-in scene's docstring on one line."""
    return " ".join((make.__doc__ or "").split())


def cmd_scenes(args) -> int:
    from warpvol.scene import SceneError
    from warpvol.scene.procedural import BUILTIN
    from warpvol.scene.toml import scene_toml

    if args.name:
        if args.name not in BUILTIN:
            from warpvol.names import did_you_mean

            raise SceneError(f"{args.name}: not a built-in scene{did_you_mean(args.name, BUILTIN)} "
                             f"(allowed: {', '.join(BUILTIN)})")
        print(scene_toml(args.name, BUILTIN[args.name]()) if args.toml else _description(BUILTIN[args.name]))
        return 0
    for name, make in BUILTIN.items():
        print(f"{name:<16} {_description(make)}")
    return 0


def _cluster_arguments(parser, what: str) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=_integer, default=None, metavar="N",
                       help=f"{what} a Dask LocalCluster of N worker processes started here (one thread each)")
    group.add_argument("--scheduler", default=None, metavar="tcp://HOST:8786",
                       help=f"{what} the Dask cluster of this scheduler (`dask scheduler`, `dask worker ADDRESS "
                            "--nthreads 1`)")


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """A warning as the tool's own line (``warpvol: warning: ...``), not Python's file, line and source."""
    return f"warpvol: warning: {message}\n"


def _render_command(sub, common) -> None:
    """The `render` command's arguments."""
    from warpvol.api import technique_names

    r = sub.add_parser("render", parents=[common], help="render a scene file or a built-in scene to .exr / .png / .npy")
    r.add_argument("scene", help="a .toml scene file or a built-in scene name (see `scenes`)")
    r.add_argument("--technique", default="reference",
                   help=f"{' | '.join(technique_names())} | auto (with --set target_error=E) (default: reference)")
    r.add_argument("--out", action="append", default=None,
                   help="output image; repeat for several (.exr .png .npy; default: SCENE.TECHNIQUE.png)")
    r.add_argument("--device", default=None, help=DEVICE_HELP)
    r.add_argument("--spp", type=_integer, default=None, help="samples per pixel (reference)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE", help="technique setting or scene key override")
    r.add_argument("--exposure", type=_finite_float, default=0.0, help="PNG exposure in stops (default 0)")
    r.add_argument("--timings", action="store_true", help="print per-stage times")
    _cluster_arguments(r, "split the reference's samples into passes on")
    r.set_defaults(func=cmd_render)


def _bench_command(sub, common) -> None:
    """The `bench` command's arguments."""
    b = sub.add_parser("bench", parents=[common], help="run a benchmark sweep, list them, or write their reports")
    b.add_argument("sweep", nargs="*", help="sweep names, or `report [SWEEP ...]` (see --list)")
    b.add_argument("--list", action="store_true", help="list the sweeps and whether they can run yet")
    b.add_argument("--quick", action="store_true", help="a reduced sweep that finishes in seconds")
    b.add_argument("--overview", action="store_true",
                   help="with `report`: write results/README.md from bench/overview.md and the pages' data")
    b.add_argument("--stale", action="store_true",
                   help="with `report`: render each page's probes again and list the pages whose images changed "
                        "since they were measured (results/stale.json)")
    b.add_argument("--device", default=None, help=DEVICE_HELP)
    b.add_argument("--out", default="results", help="results folder (default: results)")
    _cluster_arguments(b, "run the sweep's points as tasks on")
    b.set_defaults(func=cmd_bench)


def _animate_command(sub, common) -> None:
    """The `animate` command's arguments."""
    a = sub.add_parser("animate", parents=[common], help="render a camera orbit or dolly, or the lights going "
                                                         "round, as a GIF, an MP4 or a folder of PNG frames")
    a.add_argument("scene", help="a .toml scene file or a built-in scene name (see `scenes`)")
    a.add_argument("--technique", default="light_shafts", help="any technique (default: light_shafts)")
    a.add_argument("--orbit", type=_integer, default=0, metavar="N", help="N frames: the camera once round its target")
    a.add_argument("--dolly", type=_integer, default=0, metavar="N",
                   help="N frames: the camera halfway in to its target")
    a.add_argument("--light", type=_integer, default=0, metavar="N", help="N frames: the lights once round the target")
    a.add_argument("--out", default=None, help="X.gif, X.mp4 (the [video] extra) or a folder for PNG frames "
                                               "(default: SCENE.TECHNIQUE.PATH.gif)")
    a.add_argument("--fps", type=_finite_float, default=24.0, help="frames per second of the GIF or MP4 (default 24)")
    a.add_argument("--exposure", type=_finite_float, default=0.0, help="exposure in stops (default 0)")
    a.add_argument("--device", default=None, help=DEVICE_HELP)
    a.add_argument("--set", action="append", metavar="KEY=VALUE", help="technique setting or scene key override")
    a.set_defaults(func=cmd_animate)


def _view_command(sub, common) -> None:
    """The `view` command's arguments."""
    v = sub.add_parser("view", parents=[common], help="look at a scene in pyvista: media, lights, surfaces, camera")
    v.add_argument("scene", help="a .toml scene file or a built-in scene name")
    v.add_argument("--screenshot", default=None, help="render off screen to this PNG instead of opening a window")
    v.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene key override")
    v.add_argument("--technique", default=None, help="also show this technique's intermediate arrays "
                   "(light_shafts: shadow-map depth surfaces, lit slice; rbf_propagation: OPV error per cell)")
    v.add_argument("--device", default=None, help="cpu | cuda (for --technique)")
    v.set_defaults(func=cmd_view)


def _live_command(sub, common) -> None:
    """The `live` command's arguments."""
    lv = sub.add_parser("live", parents=[common], help="a window whose image re-renders as you drag the camera "
                                                        "round (t: next technique, r: the reference)")
    lv.add_argument("scene", help="a .toml scene file or a built-in scene name")
    lv.add_argument("--technique", default="light_shafts", help="the technique to start with (default: light_shafts)")
    lv.add_argument("--size", default="160x120", help="the rendered image, WxH (default 160x120)")
    lv.add_argument("--frames", type=_integer, default=0, metavar="N", help="orbit once round by itself in N frames")
    lv.add_argument("--screenshot", default=None, help="run off screen (with --frames) and save the last view here")
    lv.add_argument("--device", default=None, help=DEVICE_HELP)
    lv.add_argument("--set", action="append", metavar="KEY=VALUE", help="technique setting or scene key override")
    lv.set_defaults(func=cmd_live)


def _demo_command(sub, common) -> None:
    """The `demo` command's arguments."""
    e = sub.add_parser("demo", parents=[common], help="a real-time technique and the reference side by side, "
                       "with each one's time and error (the first thing to run)")
    e.add_argument("scene", nargs="?", default="hazy-sun", help="a scene file or built-in name (default: hazy-sun)")
    e.add_argument("--technique", default="light_shafts", help="the real-time technique (default: light_shafts)")
    e.add_argument("--out", default="demo.png", help="the side-by-side image (default: demo.png)")
    e.add_argument("--device", default=None, help=DEVICE_HELP)
    e.add_argument("--set", action="append", metavar="KEY=VALUE", help="scene key override, e.g. camera.width=320")
    e.set_defaults(func=cmd_demo)


def _docs_command(sub, common) -> None:
    """The `docs` command's arguments."""
    d = sub.add_parser("docs", parents=[common], help="write docs/scene-format.md and the generated tables of docs/ "
                       "and README from the code (--check: only say which are out of date)")
    d.add_argument("--root", default=".", help="the checkout (default: .)")
    d.add_argument("--check", action="store_true", help="write nothing; exit 1 if a page is out of date")
    d.set_defaults(func=cmd_docs)


def _scenes_command(sub, common) -> None:
    """The `scenes` command's arguments."""
    s = sub.add_parser("scenes", parents=[common],
                       help="list the built-in scenes, or print one (--toml: as a scene file)")
    s.add_argument("name", nargs="?", default=None, help="a built-in scene: its description, or with --toml its TOML")
    s.add_argument("--toml", action="store_true", help="print the scene as a TOML file to start your own from")
    s.set_defaults(func=cmd_scenes)


def main(argv: list[str] | None = None) -> int:
    from warpvol import device

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--verbose", action="store_true", help="also show Warp's and VTK's own messages")
    parser = _Parser(prog="python -m warpvol", description="Participating media with NVIDIA Warp.")
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (_render_command, _bench_command, _animate_command, _view_command, _live_command, _demo_command,
                _docs_command, _scenes_command):
        add(sub, common)
    args = parser.parse_args(argv)
    device.set_verbose(args.verbose)
    from warpvol.device import DeviceError
    from warpvol.pipeline import SettingsError
    from warpvol.scene import SceneError

    warnings.formatwarning = _one_line_warning
    try:
        return args.func(args)
    except (SceneError, SettingsError, DeviceError) as exc:
        print(f"warpvol: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # e.g. an output path that cannot be written
        print(f"warpvol: error: {exc}", file=sys.stderr)
        return 2
