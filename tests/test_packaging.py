"""The wheel holds one top-level package, warpvol: every package folder is listed in
pyproject.toml, bench/ and viz/ under their installed names warpvol.bench and warpvol.viz."""

import os
import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = os.path.join(os.path.dirname(__file__), "..")
INSTALLED_AS = {"warpvol": "warpvol", "bench": "warpvol.bench", "viz": "warpvol.viz"}


def test_every_package_folder_is_installed_under_warpvol():
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as fh:
        setuptools = tomllib.load(fh)["tool"]["setuptools"]
    found = set()
    for top, name in INSTALLED_AS.items():
        for folder, dirs, files in os.walk(os.path.join(ROOT, top)):
            dirs[:] = [d for d in dirs if d != "__pycache__"]
            if "__init__.py" in files:
                rel = os.path.relpath(folder, os.path.join(ROOT, top))
                found.add(name if rel == "." else f"{name}.{rel.replace(os.sep, '.')}")
    assert set(setuptools["packages"]) == found
    assert {p.split(".")[0] for p in setuptools["packages"]} == {"warpvol"}
    assert setuptools["package-dir"] == {v: k for k, v in INSTALLED_AS.items()}


def test_bench_and_viz_import_as_warpvol_subpackages():
    import importlib.util

    import warpvol.bench.sweeps

    assert warpvol.bench.sweeps.SWEEPS
    assert importlib.util.find_spec("warpvol.viz") is not None


def test_bench_and_viz_read_techniques_through_their_public_api():
    """bench/ and viz/ read a technique's state through ``Renderer.diagnostics()`` and
    ``arrays()``, and call its public methods: no attribute of a technique object is read
    (but its class constants), and no private attribute of anything but their own objects."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    allowed = {"NAME", "SETTINGS", "QUALITY", "LEAVES_OUT", "device", "settings", "scene"}
    hits = []
    for path in sorted([*root.joinpath("bench").rglob("*.py"), *root.joinpath("viz").rglob("*.py")]):
        tree = ast.parse(path.read_text())
        holders = {t.id for node in ast.walk(tree) if isinstance(node, ast.Assign)
                   and isinstance(node.value, ast.Attribute) and node.value.attr == "technique"
                   for t in node.targets if isinstance(t, ast.Name)}
        called = {id(node.func) for node in ast.walk(tree) if isinstance(node, ast.Call)}
        for node in ast.walk(tree):
            if not isinstance(node, ast.Attribute):
                continue
            on_technique = (isinstance(node.value, ast.Attribute) and node.value.attr == "technique") or (
                isinstance(node.value, ast.Name) and node.value.id in holders)
            if on_technique and id(node) not in called and node.attr not in allowed:
                hits.append(f"{path.name}:{node.lineno}: .{node.attr} of a technique")
            private = node.attr.startswith("_") and not node.attr.startswith("__")
            if private and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                hits.append(f"{path.name}:{node.lineno}: private .{node.attr}")
    assert not hits, hits


def _kernels():
    """Every ``@wp.kernel`` in warpvol: (module path, the function's AST node)."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "warpvol"
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and any(
                    ast.unparse(d).startswith(("wp.kernel", "warp.kernel")) for d in node.decorator_list):
                yield path.relative_to(root.parent), node


def test_every_kernel_follows_the_launch_convention():
    """``device.launch`` splits a CPU launch into index ranges and passes each range's start first:
    a kernel that does not take ``offset: int`` first, or decodes its index by hand (``wp.tid()``)
    other than as ``wp.tid() + offset``, runs each chunk's threads on the first chunk's
    indices. And no launch goes around ``device.launch`` (``wp.launch`` outside device.py). (The
    decoding is written in each kernel: Warp allows ``wp.tid()`` in kernels only, not in a function.)"""
    import ast
    from pathlib import Path

    kernels = list(_kernels())
    assert len(kernels) > 50  # the walk found them
    bad = []
    for path, node in kernels:
        first = node.args.args[0] if node.args.args else None
        if first is None or first.arg != "offset" or ast.unparse(first.annotation) != "int":
            bad.append(f"{path}:{node.name}: first argument is not offset: int")
        src = ast.unparse(node)
        if src.count("wp.tid()") != 1 or src.count("wp.tid() + offset") != 1:
            bad.append(f"{path}:{node.name}: index not read once as wp.tid() + offset")
    root = Path(__file__).resolve().parent.parent / "warpvol"
    bad += [f"{p.relative_to(root.parent)}: wp.launch outside device.py" for p in root.rglob("*.py")
            if p.name != "device.py" and "wp.launch(" in p.read_text()]
    assert not bad, "\n".join(bad)


def test_every_kernel_module_is_registered_and_built_for_cuda():
    """A module with kernels calls ``device.kernel_module(__name__)`` (warpvol's module options,
    and the list ``bench.cuda_compile`` builds for CUDA), and importing the techniques imports it:
    else CI's CUDA build would pass over it and it could stop building unseen."""
    import warpvol as wv
    from warpvol import device

    for name in wv.technique_names():
        wv.technique_class(name)
    files = sorted({str(path) for path, _ in _kernels()})
    modules = {f.removesuffix(".py").removesuffix("/__init__").replace("/", ".") for f in files}
    assert len(modules) > 10
    unregistered = sorted(modules - set(device.KERNEL_MODULES))
    assert not unregistered, f"kernel modules not registered by importing the techniques: {unregistered}"


def test_every_medium_kind_exposes_the_same_interface():
    """Each medium kind's module exposes sigma_t at a point, its optical depth in closed form (a
    grid: its transmittance by ratio tracking instead) and a free flight, with the same arguments
    in the same order, so ``media/volume.py``'s dispatch is one call a kind."""
    import ast
    from pathlib import Path

    media = Path(__file__).resolve().parent.parent / "warpvol" / "media"
    want = {"extinction": ["sigma", "x"], "tau": ["sigma", "o", "d", "t0", "t1"],
            "transmittance": ["sigma", "o", "d", "t0", "t1", "c", "rng"],
            "free_flight": ["sigma", "o", "d", "t0", "t1", "c", "rng"]}
    kinds = {"homogeneous": ("shape", "Shape", ("extinction", "tau", "free_flight")),
             "grid": ("grid", "Grid", ("extinction", "transmittance", "free_flight")),
             "rbf": ("rbf", "Gaussians", ("extinction", "tau", "free_flight")),
             "particles": ("particle", "Particles", ("extinction", "tau", "free_flight"))}
    for module, (prefix, struct, functions) in kinds.items():
        defs = {n.name: n for n in ast.parse((media / f"{module}.py").read_text()).body if isinstance(n, ast.FunctionDef)}
        for f in functions:
            node = defs.get(f"{prefix}_{f}")
            assert node is not None, f"media/{module}.py has no {prefix}_{f}"
            args = [a.arg for a in node.args.args]
            assert ast.unparse(node.args.args[0].annotation) == struct, f"{prefix}_{f} does not take the {struct} first"
            assert args[1:] == want[f], f"{prefix}_{f}{tuple(args)}: not the interface's arguments"
