"""Reports from the sweeps' JSON: ``results/<sweep>/README.md`` and one PNG plot per device.

    python -m warpvol bench report [SWEEP ...] [--out results]

Paper sweeps: our table beside the paper's (paper FPS, ours, both normalised to the
table's first row, so the shape of cost growth can be compared across hardware).
Accuracy sweeps: relative RMSE against ms per frame, with the error-vs-time front.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

import warpvol as wv

from .sweeps import SWEEPS


def _fmt(x, digits=3) -> str:
    if x is None:
        return "–"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def _params(row) -> str:
    return ", ".join(f"{k}={v}" for k, v in row["params"].items())


def _flip(row) -> str:
    """A row's mean HDR-FLIP against its reference (``metrics.hdr_flip``), or a dash."""
    return f"{row['hdr_flip']:.3f}" if row.get("hdr_flip") is not None else "–"


def _stages(row) -> str:
    return ", ".join(f"{n} {s['median_ms']:.2f}" for n, s in row["stages"].items() if s["status"] == "ran")


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats in both time and error, by increasing time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], np.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, ax, png: Path, grid: bool = True) -> None:
    """Legend (and log grid), tight layout, write the PNG, free the figure."""
    ax.legend(fontsize=8)
    if grid:
        ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    _plt().close(fig)


def accuracy_section(rows: list[dict], png: Path) -> list[str]:
    pts = [(r["median_ms"], r["rel_rmse_corrected"]) for r in rows]
    front = set(pareto_front(pts))
    extra = next((k for k in ("rel_rmse_raymarch", "rel_rmse_multiple", "mean_ratio") if k in rows[0]), None)  # a second yardstick
    label = {"rel_rmse_raymarch": "vs raymarch", "rel_rmse_multiple": "vs the multiple-scattering reference",
             "mean_ratio": "image mean ÷ the reference's"}
    lines = ["| parameters | ms / frame (min..max) | relative RMSE to the reference | same, its noise removed "
             + (f"| {label[extra]} " if extra else "") + "| on the front | stages ran (ms) | peak MB |",
             "|---|---|---|---|---|---|---|" + ("---|" if extra else "")]
    def corrected(r) -> str:  # below 0.15 x the reference's noise the difference cannot be told from it
        floor = r["reference"]["rel_rmse_floor"]
        return f"{r['rel_rmse_corrected']:.4f}" if r["rel_rmse_corrected"] >= 0.15 * floor else f"< {0.15 * floor:.4f} (unresolved)"

    for i, r in enumerate(rows):
        lo, hi = r["spread_ms"]
        lines.append(f"| {_params(r)} | {r['median_ms']:.2f} ({lo:.2f}..{hi:.2f}) | {r['rel_rmse']:.4f} | "
                     f"{corrected(r)} | " + (f"{r.get(extra, float('nan')):.4f} | " if extra else "")
                     + f"{'yes' if i in front else ''} | {_stages(r)} | {r['peak_mem_mb']:.0f} |")
    if "rel_rmse_band" in rows[0]:  # objects in clouds: the error where the surface lies inside the cloud
        lines += ["", "| parameters | relative RMSE where the surface lies inside a block | pixels |", "|---|---|---|"]
        lines += [f"| {_params(r)} | {r['rel_rmse_band']:.4f} | {r['band_pixels']} |" for r in rows]
    if "rel_rmse_core" in rows[0]:  # a light's singular core apart from the rest of the image
        lines += ["", "| parameters | RMSE in the lamp's core ÷ image mean | outside it ÷ image mean | core pixels |",
                  "|---|---|---|---|"]
        lines += [f"| {_params(r)} | {r['rel_rmse_core']:.4f} | {r['rel_rmse_rest']:.4f} | {r['core_pixels']} |"
                  for r in rows]
        from .sweeps.particle_glow import CORE_ANGLE

        lines += ["", "Against the multiple-scattering reference, the error split at the lamp's core (the pixels "
                  f"within {CORE_ANGLE:g} rad of the lamp as the camera sees it) and the rest; both are RMSEs over their own "
                  "pixels divided by the whole image's mean, so the image's squared error is their squares weighted "
                  "by their shares of the pixels."]
    floor = rows[0]["reference"]["rel_rmse_floor"]
    lines += ["", f"Reference: {rows[0]['reference']['spp']} spp, pixel centres, max_bounces = "
              f"{rows[0]['reference']['max_bounces']}. Its own noise, estimated from two seeds, is a relative "
              f"RMSE of {floor:.4f}; it adds in quadrature (E[e²] = error² + noise²), so the noise-removed "
              "column is sqrt(max(e² − noise², 0)). With this many pixels the noise estimate is good to about "
              "1%, which resolves errors down to roughly 0.15 × the noise (the plot's dotted line)."]
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    keys = sorted({k for r in rows for k in r["params"]})
    group_key = keys[0] if len(keys) > 1 else None  # first parameter: one series per value
    groups = {}
    for r in rows:
        groups.setdefault(r["params"].get(group_key), []).append(r)
    for value, rs in groups.items():
        ax.plot([r["median_ms"] for r in rs], [r["rel_rmse_corrected"] for r in rs], "o-", ms=4,
                label=f"{group_key}={value}" if group_key else None)
    f = sorted(front, key=lambda i: pts[i][0])
    ax.plot([pts[i][0] for i in f], [pts[i][1] for i in f], "k--", lw=1, label="front")
    ax.axhline(0.15 * floor, color="grey", lw=0.8, ls=":", label="resolution (0.15 × reference noise)")
    ax.set(xscale="log", yscale="log", xlabel="ms per frame", ylabel="relative RMSE vs reference (its noise removed)",
           title=f"{rows[0]['sweep']} — {rows[0]['device']}")
    _save(fig, ax, png)
    return lines


def _n_exponents(rows: list[dict]) -> list[str]:
    """The frame's and each stage's fitted exponent in N over the rows that vary N alone."""
    d0 = rows[0]["params"].get("directions")
    rs = [r for r in rows if set(r["params"]) == {"particles", "directions"} and r["params"]["directions"] == d0]
    if len(rs) < 3:
        return []
    n = np.array([r["params"]["particles"] for r in rs], float)
    big = n >= 2048
    out = ["", f"Cost in N at D = {d0} (least squares of log ms against log N; 1 is linear, 2 quadratic):", ""]
    series = {"frame": [r["median_ms"] for r in rs]}
    for stage in ("direct", "emission", "iterate", "splat"):
        series[stage] = [r["stages"].get(stage, {}).get("median_ms", np.nan) for r in rs]
    for name, ms in series.items():
        ms = np.array(ms, float)
        tail = f", {fitted_exponent(n[big], ms[big]):.2f} from N = 2048 up" if big.sum() >= 2 else ""
        out.append(f"- {name}: N^**{fitted_exponent(n, ms):.2f}** over N = {n.min():.0f}..{n.max():.0f}{tail}")
    return out


def paper_section(rows: list[dict], png: Path) -> list[str]:
    ours = [1000.0 / r["median_ms"] for r in rows]
    paper = [r["paper"] if isinstance(r.get("paper"), (int, float)) else None for r in rows]
    p0 = paper[0]
    # rows of several set-ups (params "setup"): each divided by its own set-up's first row
    first = {}
    for r, o in zip(rows, ours):
        first.setdefault(r["params"].get("setup"), o)
    base = [first[r["params"].get("setup")] for r in rows]
    it = "iteration_ms" in rows[0]  # illumination networks: one iteration timed alone
    tex = "impostor_res" in rows[0]  # depth impostors: the camera impostors' texels a side
    lines = ["| parameters | paper FPS | ours FPS | paper ÷ first row | ours ÷ first row | stages ran (ms) | peak MB |"
             + (" one iteration ms | GFLOP/s | of FP32 peak | network build ms |" if it else "")
             + (" gather tests (M) | impostor texels T |" if tex else ""),
             "|---|---|---|---|---|---|---|" + ("---|---|---|---|" if it else "") + ("---|---|" if tex else "")]
    for r, o, p, b in zip(rows, ours, paper, base):
        extra = f" {r.get('gather_tests', 0) / 1e6:.2f} | {r['impostor_res'] or '–'} |" if tex else ""
        if it:
            frac = r.get("peak_fraction")
            extra += (f" {r['iteration_ms']:.2f} | {r['gflops']:.1f} | {f'{100 * frac:.1f}%' if frac else '–'} | "
                     f"{r['network_ms']:.1f} |")
        lines.append(f"| {_params(r)} | {_fmt(p)} | {o:.1f} | {_fmt(p / p0 if p and p0 else None)} | "
                     f"{o / b:.3f} | {_stages(r)} | {r['peak_mem_mb']:.0f} |" + extra)
    if it and rows[0].get("peak_gflops"):
        lines += ["", f"FP32 peak taken as {rows[0]['peak_gflops']:.0f} GFLOP/s (for a CPU: cores × clock × SIMD "
                  "lanes × 2, one FMA unit per core; for a GPU the vendor's figure). One iteration is "
                  "2·3·N·D² flops (the product S = I·P; the gather is not counted)."]
    if it:
        lines += _n_exponents(rows)
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    x = np.arange(len(rows))
    for setup in first:
        k = [i for i, r in enumerate(rows) if r["params"].get("setup") == setup]
        ax.plot(x[k], [ours[i] / first[setup] for i in k], "o-",
                label=f"ours ({rows[0]['device']}{f', {setup} set-up' if setup else ''})")
    if p0:
        ax.plot(x, [p / p0 if p else np.nan for p in paper], "s--", label="paper")
    ax.set_xticks(x, [_params(r) for r in rows], rotation=30, ha="right", fontsize=7)
    ax.set(ylabel="FPS ÷ first row", title=rows[0]["sweep"])
    _save(fig, ax, png, grid=False)
    return lines


def lightpass_section(rows: list[dict], png: Path) -> list[str]:
    lines = ["| parameters | texels M | direct ms (2 suns) | direct light, relative RMSE to the exact sphere mean | "
             "image moves by (relative RMSE to the exact-direct image) | image vs reference (its noise removed) |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {_params(r)} | {r['texels'] or '–'} | {r['direct_ms']:.2f} | {r['direct_rel_rmse']:.4f} | "
                     f"{r['image_move']:.4f} | {r['rel_rmse_corrected']:.4f} |")
    floor = rows[0]["reference"]["rel_rmse_floor"]
    lines += ["", "The exact sphere mean: light_pass = 0 at 256 points a sphere. light_pass 0 = exact (BVH ray "
              "queries), 1 = depth slices, 2 = Fourier opacity map; the first row is the direct stage as it was "
              f"before the light pass. Reference: {rows[0]['reference']['spp']} spp, its own noise a relative RMSE "
              f"of {floor:.4f} (removed in quadrature)."]
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for kind, label in ((0, "exact (points a sphere)"), (1, "depth slices S"), (2, "Fourier terms K")):
        rs = [r for r in rows if r["params"].get("light_pass") == kind]
        if rs:
            ax.plot([r["direct_ms"] for r in rs], [r["direct_rel_rmse"] for r in rs], "o-", ms=4, label=label)
    ax.set(xscale="log", yscale="log", xlabel="direct stage ms (2 suns)",
           ylabel="direct light: relative RMSE to the exact mean", title=f"{rows[0]['sweep']} — {rows[0]['device']}")
    _save(fig, ax, png)
    return lines


def overhead_section(rows: list[dict], png: Path | None) -> list[str]:
    lines = ["| case | frame ms (median) | overhead µs | frames |", "|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['params']['case']} | {r['median_ms']:.4f} | {r['overhead_us']:.1f} | {r['frames']} |")
    return lines


def edges_section(rows: list[dict], png: Path | None) -> list[str]:
    lines = ["| M | block sum | pixels within M/2 of a depth jump | error there | error elsewhere | ms / frame |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        kind = "depth-aware" if r["params"].get("edges") else "paper (separable)"
        lines.append(f"| {r['params']['block']} | {kind} | {100 * r['edge_pixels']:.1f}% | {r['rel_err_edges']:.4f} | "
                     f"{r['rel_err_elsewhere']:.4f} | {r['median_ms']:.1f} |")
    return lines + ["", "Errors are mean |interleaved − N-per-pixel| over the pixels, divided by the image mean."]


def speedup_section(rows: list[dict], png: Path | None) -> list[str]:
    lines = ["| N | M | march, M = 1: min (median) ms | march, M x M: min (median) ms | speed-up of the mins "
             "(of the medians) | ÷ M² |", "|---|---|---|---|---|---|"]
    for r in rows:
        a, b = r["march_ms_m1"], r["march_ms"]
        lines.append(f"| {r['params']['steps']} | {r['params']['block']} | {a['min']:.1f} ({a['median']:.1f}) | "
                     f"{b['min']:.1f} ({b['median']:.1f}) | {r['speedup']:.1f}× ({r['speedup_median']:.1f}×) | "
                     f"{r['fraction_of_m2']:.2f} |")
    return lines + ["", f"The two settings are timed in alternation in one process ({rows[0]['frames']} rounds), so "
                    "drift in the machine's speed hits both; the march stage only (shadow maps, visible surface and "
                    "shading are the same for both)."]


def rules_section(rows: list[dict], png: Path | None) -> list[str]:
    lines = ["| grid | rule | wavefront | mean abs error | mean exact | relative | 95th pct of per-cell relative "
             "| max abs error | propagate ms |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        p = r["params"]
        lines.append(f"| {p['grid']} | {'paper' if p['rule'] == 0 else 'corrected'} | {p['wavefront']} | "
                     f"{r['mean_abs_error']:.4g} | {r['mean_exact']:.4g} | {r['rel_error']:.4f} | "
                     f"{r['p95_rel_cell']:.4f} | {r['max_abs_error']:.4g} | {r['stages']['propagate']['median_ms']:.2f} |")
    return lines + ["", "Errors are per cell and light (red channel), against optical depth marched through the "
                    "same extinction volume in 8 steps per cell width."]


def fitted_exponent(work, ms) -> float:
    """Least-squares slope of log(ms) against log(work)."""
    return float(np.polyfit(np.log(work), np.log(ms), 1)[0])


def scaling_section(rows: list[dict], png: Path) -> list[str]:
    lines = ["| stage | parameters | work | stage ms |", "|---|---|---|---|"]
    fits = {}
    for r in rows:
        stage = r["params"]["stage"]
        lines.append(f"| {stage} | {_params(r)} | {r['work']:.3g} | {r['stage_ms']:.2f} |")
        fits.setdefault(stage, []).append((r["work"], r["stage_ms"]))
    lines.append("")
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for stage, pts in fits.items():
        work, ms = np.array(pts).T
        k = fitted_exponent(work, ms) if len(pts) > 1 else float("nan")
        unit = "cells x sweeps" if stage == "propagate" else "pixels x steps"
        lines.append(f"- {stage}: time ∝ ({unit})^**{k:.2f}** (least squares in log-log over {len(pts)} points; "
                     "1 is proportional)")
        ax.loglog(work, ms, "o", label=f"{stage}: exponent {k:.2f}")
    ax.set(xlabel="work (cells x sweeps, pixels x steps)", ylabel="stage ms", title=rows[0]["sweep"])
    _save(fig, ax, png)
    return lines


def convergence_section(rows: list[dict], png: Path) -> list[str]:
    lines = ["| parameters | iteration | change per iteration | error of I to the converged | image error to the "
             "converged |", "|---|---|---|---|---|"]
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for r in rows:
        change, err = r["change"], r["network_error"]
        for k in sorted(int(k) for k in r["image_error"]):
            e = f"{err[k - 1]:.2e}" if k <= len(err) else "–"
            lines.append(f"| {_params(r)} | {k} | {change[k - 1]:.2e} | {e} | {r['image_error'][str(k)]:.2e} |")
        x = np.arange(1, len(change) + 1)
        ax.semilogy(x, change, "-", label=f"{_params(r)}: change per iteration")
        ax.semilogy(np.arange(1, len(err) + 1), err, "--", label=f"{_params(r)}: error of I to converged")
    ax.set(xlabel="iterations from zero", ylabel="relative L2", title=rows[0]["sweep"])
    _save(fig, ax, png)
    for r in rows:
        if r.get("images"):
            lines += ["", f"{_params(r)}: " + " ".join(f"![{k} iterations]({f})" for k, f in r["images"].items()),
                      "", "Left to right: " + ", ".join(f"{k} iterations" for k in r["images"]) + "."]
    return lines


def bound_section(rows: list[dict], png: Path | None) -> list[str]:
    lines = ["| parameters | eps: single-scattering RMSE | total: converged RMSE | eps / (1 − a) | holds | "
             "reference noise (relative, ss / ms) |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {_params(r)} | {r['eps_rmse']:.4g} | {r['total_rmse']:.4g} | {r['bound']:.4g} | "
                     f"{'yes' if r['holds'] else 'no'} | {r['reference_floor'][0]:.4f} / {r['reference_floor'][1]:.4f} |")
    return lines


def animated_section(rows: list[dict], png: Path) -> list[str]:
    lines = ["| parameters | frame ms (median) | network stage ms | mean error vs full rebuild (frames ≥ F/4) | "
             "last frame's error |", "|---|---|---|---|---|"]
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for r in rows:
        lines.append(f"| {_params(r)} | {r['median_ms']:.1f} | {r['network_ms']:.2f} | {r['mean_error']:.4f} | "
                     f"{r['final_error']:.4f} |")
        if r["params"].get("refresh"):
            ax.plot(np.arange(1, len(r["error_per_frame"]) + 1), r["error_per_frame"], label=_params(r))
    ax.set(xlabel="frame", ylabel="relative RMSE vs full rebuild", title=rows[0]["sweep"])
    _save(fig, ax, png)
    return lines


#: Image means within this fraction of each other are the same picture at 64 spp (the means' own noise is
#: far below it); beyond it Mitsuba rendered another scene (an exporter's approximation) and the time
#: ratio compares different work.
SAME_MEAN = 0.02


def speed_section(rows: list[dict], png: Path | None) -> list[str]:
    lines = ["| scene | spp | seconds | paths / s | per core | image mean | Mitsuba 3 (variant) seconds | ours ÷ Mitsuba time |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        mi = r.get("mitsuba")
        theirs = f"{mi['seconds']:.2f} ({mi['variant']}, mean {mi['mean']:.4f})" if mi else "–"
        ratio = f"{r['seconds'] / mi['seconds']:.2f}" if mi else "–"
        if mi and r["params"]["spp"] >= 64 and abs(mi["mean"] / r["mean"] - 1.0) > SAME_MEAN:
            ratio += f" (not the same image: Mitsuba's mean {mi['mean'] / r['mean'] - 1.0:+.1%})"
        lines.append(f"| {r['scene']} | {r['params']['spp']} | {r['seconds']:.2f} | {r['paths_per_s']:.3g} | "
                     f"{r['paths_per_s_per_core']:.3g} | {r['mean']:.4f} | {theirs} | {ratio} |")
    lines += ["", "A path is one camera sample of one pixel (three where extinction differs per channel: each "
              "channel is traced alone). Times exclude a first 1-spp frame (compile, upload, BVH build). Where "
              f"the two images' means differ by more than {SAME_MEAN:.0%} at 64 spp or more, Mitsuba rendered the scene as its "
              "exporter approximates it (a grid or RBF medium resampled), and the ratio is marked: it compares "
              "different work."]
    return lines


def table_section(rows: list[dict], png: Path) -> list[str]:
    """Each row's ``table`` fields, its frame time and stages, and the images it shows."""
    keys = list(rows[0]["table"])
    lines = ["| parameters | ms / frame | " + " | ".join(keys) + " | stages ran (ms) |",
             "|---|---|" + "---|" * len(keys) + "---|"]
    for r in rows:
        cells = [f"{v:.4g}" if isinstance(v, float) else str(v) for v in (r["table"].get(k, "") for k in keys)]
        lines.append(f"| {_params(r)} | {r['median_ms']:.1f} | " + " | ".join(cells) + f" | {_stages(r)} |")
    shown = [r for r in rows if r.get("images")]
    if shown:
        lines += ["", " ".join(f"![{_params(r)}]({f})" for r in shown for f in r["images"].values()), "",
                  "Images, left to right: " + "; ".join(_params(r) for r in shown) + "."]
    lines += ["", f"Scene: {rows[0].get('scene', '')}."]
    return lines


MODEL_ERROR = Path(__file__).resolve().parents[1] / "warpvol" / "model_error.json"


def write_model_error(rows: list[dict]) -> None:
    """For ``technique="auto"``: per family and technique its lowest measured error against the
    physical answer, the frame time and settings that reached it, and every point measured
    (``front``: error, ms, settings; for ``frame_ms``) (from accuracy-vs-time)."""
    families: dict = {}
    for r in rows:
        p = r["params"]
        if p["technique"] in ("reference", "mitsuba"):  # the fallback and a yardstick, not techniques
            continue
        family = families.setdefault(p["family"], {"media": r.get("media", []), "techniques": {}, "front": []})
        family["front"].append({"technique": p["technique"], "error": round(r["rel_rmse_corrected"], 4),
                                "ms": round(r["median_ms"], 1),
                                "settings": {k: v for k, v in p.items() if k not in ("family", "technique")}})
        best = family["techniques"].get(p["technique"])
        if best is None or r["rel_rmse_corrected"] < best["error"]:
            family["techniques"][p["technique"]] = {
                "error": round(r["rel_rmse_corrected"], 4), "ms": round(r["median_ms"], 1),
                "settings": {k: v for k, v in p.items() if k not in ("family", "technique")}}
    doc = {"from": "results/accuracy-vs-time (python -m warpvol bench accuracy-vs-time)", "device": rows[0]["device"],
           "commit": rows[0]["commit"], "image": rows[0]["scene"].split()[-1], "families": families}
    MODEL_ERROR.write_text(json.dumps(doc, indent=1) + "\n")


def front_section(rows: list[dict], png: Path) -> list[str]:
    """Per scene family, every technique's error against the physical answer over its frame
    time, one line per technique on a log-log plot, and the table; ``model_error.json`` from it."""
    lines = _front_plot_and_table(rows, png)
    if not png.stem.endswith("-quick"):  # a quick sweep's tiny images do not speak for the families
        write_model_error(rows)
    floor = rows[0]["reference"]["rel_rmse_floor"]
    lines += ["", "`technique=\"auto\"` reads the best error and its time per family and technique from "
              "`warpvol/model_error.json`, written with this page.",
              "", f"The physical answer: the reference with all orders of scattering, {rows[0]['reference']['spp']} spp "
              f"at pixel centres (its own relative noise {floor:.4f} for the first family, removed in quadrature). "
              "A frame runs every stage its technique has (nothing cached). Mitsuba's rows (a box filter over each "
              "pixel) are scored against the reference over pixel areas, and its time is its render after a warm-up "
              "one. Where surfaces sit inside the fog (fog and occluders) Mitsuba takes a ray leaving them to be in "
              "vacuum, and with a point light inside albedo-1 fog its finite-spp mean falls short "
              "(tests/test_mitsuba.py): there it is not the yardstick the reference is."]
    return lines


def _front_plot_and_table(rows: list[dict], png: Path) -> list[str]:
    """Per scene family a log-log plot of error against frame time, one line per technique (and
    one for it with the multiple-scattering term), and the table of every row."""
    families = list(dict.fromkeys(r["params"]["family"] for r in rows))
    plt = _plt()
    techniques = list(dict.fromkeys(r["params"]["technique"] for r in rows))
    colour = {t: plt.get_cmap("tab10")(i % 10) for i, t in enumerate(techniques)}  # one colour a technique, every panel
    cols = min(2, len(families))
    fig, axes = plt.subplots(-(-len(families) // cols), cols, figsize=(6.0 * cols, 4.2 * -(-len(families) // cols)),
                             squeeze=False)
    lines = ["| family | technique | quality | ms / frame | relative RMSE (noise removed) | ꟻLIP | image mean ÷ reference | "
             "leaves out |", "|---|---|---|---|---|---|---|---|"]
    for ax, family in zip(axes.flat, families):
        rs = [r for r in rows if r["params"]["family"] == family]
        for technique in dict.fromkeys(r["params"]["technique"] for r in rs):
            for ms in (False, True):  # without and with the multiple-scattering lattice
                t_rows = [r for r in rs if r["params"]["technique"] == technique and
                          bool(r["params"].get("multiple_scattering", 0)) == ms]
                if t_rows:
                    ax.plot([r["median_ms"] for r in t_rows], [max(r["rel_rmse_corrected"], 1e-4) for r in t_rows],
                            "s--" if ms else "o-", ms=4, label=technique + (" + multiple scattering" if ms else ""),
                            color=colour[technique])
        ax.set(xscale="log", yscale="log", xlabel="ms per frame", ylabel="relative RMSE vs the physical answer",
               title=f"{family} ({rs[0]['scene']})")
        ax.legend(fontsize=7)
        ax.grid(True, which="both", lw=0.3)
        for r in rs:
            q = ", ".join(f"{k}={v}" for k, v in r["params"].items() if k not in ("family", "technique"))
            lines.append(f"| {family} | {r['params']['technique']} | {q} | {r['median_ms']:.1f} | "
                         f"{r['rel_rmse_corrected']:.4f} | {_flip(r)} | {r['mean_ratio']:.3f} | "
                         f"{'; '.join(r['leaves_out']) or '–'} |")
    for ax in list(axes.flat)[len(families):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return lines


def multiple_section(rows: list[dict], png: Path) -> list[str]:
    """The multiple-scattering page: per family each marcher without the term (its defaults and
    four times its knob) and with it; the lattice's ladder and the reference's error over its
    time; and the plot of every row's error over its time."""
    marchers = [r for r in rows if set(r["params"]) - {"family", "technique", "multiple_scattering", "ms_directions"}]
    lines = ["| family | technique | off (paper's model) | off, 4x the knob | on (defaults) | time on ÷ off | "
             "mean ÷ reference, off / on |", "|---|---|---|---|---|---|---|"]
    by = {}
    for r in marchers:
        p = r["params"]
        if p["technique"] == "reference":
            continue
        key = (p["family"], p["technique"])
        if p.get("multiple_scattering"):
            if key + ("on",) in by:  # the technique's defaults come first; later rows are the ladder's
                continue
            kind = "on"
        else:
            kind = "off" if key + ("off",) not in by else "off4"
        by[key + (kind,)] = r
    for family, technique in dict.fromkeys((k[0], k[1]) for k in by):
        off, off4, on = (by.get((family, technique, k)) for k in ("off", "off4", "on"))
        if not (off and off4 and on):
            continue
        lines.append(f"| {family} | {technique} | {off['rel_rmse_corrected']:.3f} ({off['median_ms']:.0f} ms) | "
                     f"{off4['rel_rmse_corrected']:.3f} ({off4['median_ms']:.0f} ms) | "
                     f"{on['rel_rmse_corrected']:.3f} ({on['median_ms']:.0f} ms) | "
                     f"{on['median_ms'] / off['median_ms']:.2f} | {off['mean_ratio']:.3f} / {on['mean_ratio']:.3f} |")
    for family in dict.fromkeys(r["params"]["family"] for r in rows):
        ladder = [r for r in rows if r["params"]["family"] == family and r["params"]["technique"] == "raymarch"
                  and set(r["params"]) == {"family", "technique", "multiple_scattering", "ms_directions"}]
        refs = [r for r in rows if r["params"]["family"] == family and r["params"]["technique"] == "reference"]
        if not ladder or not refs:
            continue
        best = min(refs, key=lambda r: r["rel_rmse_corrected"])  # its noise ~ spp^-1/2: time to E ~ (e / E)^2

        def ref_time(e: float, best=best) -> float:
            return best["median_ms"] * (best["rel_rmse_corrected"] / max(e, 1e-6)) ** 2

        lines += ["", f"**{family}**: raymarch's lattice doubled, against the reference's time to the same error "
                  f"(from its {best['params']['spp']} spp row: {best['rel_rmse_corrected']:.4f} in "
                  f"{best['median_ms']:.0f} ms, its error falling as spp^-1/2).", "",
                  "| multiple_scattering, ms_directions | ms / frame | relative RMSE | observed order | orders, tail ratio "
                  "| the reference's time to it | ratio |", "|---|---|---|---|---|---|---|"]
        prev = None
        for r in ladder:
            e = r["rel_rmse_corrected"]
            t_ref = ref_time(e)
            order = f"{math.log2(prev / e):.2f}" if prev and e > 0 else "–"
            sc = r.get("scattering", {})
            tail = ", ".join(f"{x:.3f}" for x in sc.get("ms_tail_ratio", [])[:1])
            lines.append(f"| {r['params']['multiple_scattering']}, {r['params']['ms_directions']} | "
                         f"{r['median_ms']:.0f} | {e:.4f} | {order} | {sc.get('ms_orders', '–')}, {tail} | "
                         f"{t_ref:.0f} ms | {r['median_ms'] / t_ref:.3f} |")
            prev = e
        rich = [r for r in rows if r["params"]["family"] == family and r["params"]["technique"] == "raymarch"
                and set(r["params"]) == {"family", "technique", "multiple_scattering", "ms_directions", "steps"}
                and r["params"]["ms_directions"] >= 4 * r["params"]["multiple_scattering"]]
        if rich:
            lines += ["", "With four directions a node axis (the floor above is the directions' quadrature) and the "
                      "march's steps given:", "",
                      "| multiple_scattering, ms_directions, steps | ms / frame | relative RMSE "
                      "| the reference's time to it | ratio |", "|---|---|---|---|---|"]
            for r in rich:
                e = r["rel_rmse_corrected"]
                t_ref = ref_time(e)
                p = r["params"]
                lines.append(f"| {p['multiple_scattering']}, {p['ms_directions']}, {p['steps']} | {r['median_ms']:.0f} "
                             f"| {e:.4f} | {t_ref:.0f} ms | {r['median_ms'] / t_ref:.3f} |")
        lines += ["", "| reference spp | ms / frame | relative RMSE |", "|---|---|---|"]
        lines += [f"| {r['params']['spp']} | {r['median_ms']:.0f} | {r['rel_rmse_corrected']:.4f} |" for r in refs]
    lines += ["", "Every row:", ""] + _front_plot_and_table(rows, png)
    return lines


def census_section(rows: list[dict], png: Path) -> list[str]:
    """The census: per built-in scene and technique its frame time at the scene's own size and at
    160x120, each over the reference's at 16 spp, the stage that costs most, and the error
    against the physical answer; a plot of error over the time ratio at 160x120."""
    from .sweeps.census import CENSUS_SIZE, reference_ms

    by: dict = {}
    for r in rows:
        p = r["params"]
        by.setdefault((p["scene"], p["technique"]), {})[(p["width"], p["height"])] = r
    lines = ["| scene | technique | own size: ms / frame (÷ reference) | 160x120: ms / frame (÷ reference) | "
             "costliest stage at 160x120 | relative RMSE | ꟻLIP | mean ÷ truth | truth: spp (both seeds), noise | leaves out |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    over = []
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    techniques = list(dict.fromkeys(t for _, t in by))
    colour = {t: plt.get_cmap("tab10")(i % 10) for i, t in enumerate(techniques)}
    plotted = set()
    for (scene, technique), sizes in by.items():
        cells = []
        for size in dict.fromkeys([next(iter(sizes)), CENSUS_SIZE]):
            r = sizes.get(size)
            ref = reference_ms(rows, scene, size)
            if r is None:
                cells.append("–")
                continue
            ratio = r["median_ms"] / ref if ref and technique != "reference" else None
            if ratio is not None and ratio > 1.0:
                over.append(f"{scene} {technique} {size[0]}x{size[1]} ({ratio:.2f}x)")
            bold = "**" if ratio is not None and ratio > 1.0 else ""
            cells.append(f"{r['median_ms']:.0f}" + (f" ({bold}{ratio:.2f}{bold})" if ratio is not None else ""))
        if len(cells) == 1 or next(iter(sizes)) == CENSUS_SIZE:
            cells = [cells[0], "(the same)"]
        small = next((r for r in sizes.values() if "rel_rmse_corrected" in r), sizes.get(CENSUS_SIZE))
        stage = err = mean = truth = "–"
        if small is not None:
            ran = {k: v["median_ms"] for k, v in small["stages"].items() if v.get("status") == "ran"}
            if ran:
                top = max(ran, key=ran.get)
                stage = f"{top} {ran[top]:.0f} ms"
            if "rel_rmse_corrected" in small:
                err, mean = f"{small['rel_rmse_corrected']:.3f}", f"{small['mean_ratio']:.3f}"
                truth = f"{small['reference']['spp']}, {small['reference']['rel_rmse_floor']:.3f}"
                ref = reference_ms(rows, scene, (small["params"]["width"], small["params"]["height"]))
                if ref and technique != "reference":
                    ax.scatter(small["median_ms"] / ref, max(small["rel_rmse_corrected"], 1e-3), s=18,
                               color=colour[technique], label=None if technique in plotted else technique)
                    plotted.add(technique)
        leaves = "; ".join("multiple scattering, indirect light: approximated (lattice)"
                           if x.startswith(wv.Frame.APPROXIMATED) else x
                           for x in (small["leaves_out"] if small is not None else [])) or "–"
        flip = _flip(small) if small is not None else "–"
        if small is not None and small.get("images", {}).get("flip"):
            flip += f" ([map]({small['images']['flip']}))"
        lines.append(f"| {scene} | {technique} | {cells[0]} | {cells[1]} | {stage} | {err} | {flip} | {mean} | "
                     f"{truth} | {leaves} |")
    ax.axvline(1.0, color="grey", lw=0.8, ls="--")
    ax.set(xscale="log", yscale="log", xlabel="frame time ÷ the reference's at 16 spp (160x120)",
           ylabel="relative RMSE vs the physical answer", title="every built-in scene, each technique at its defaults")
    _save(fig, ax, png)
    lines += ["", f"Rows over the reference's time at 16 spp: {'; '.join(over) if over else 'none'}.", "",
              "A map is the row's per-pixel HDR-ꟻLIP error against the physical answer in false colour (magma: black "
              "is no visible difference, yellow the most), to see where a technique errs."]
    return lines


SECTIONS = {"multiple": multiple_section, "animated": animated_section, "convergence": convergence_section, "bound": bound_section, "accuracy": accuracy_section, "scaling": scaling_section, "rules": rules_section, "paper": paper_section, "overhead": overhead_section, "speed": speed_section,
            "edges": edges_section, "speedup": speedup_section, "lightpass": lightpass_section, "table": table_section,
            "front": front_section, "census": census_section}


def write_report(out: Path, name: str) -> Path | None:
    """Write ``out/<name>/README.md`` (and plots) from the JSON there; None if there is none."""
    sweep = SWEEPS[name]
    folder = Path(out) / name
    files = sorted(folder.glob("*.json"))
    if not files:
        return None
    md = [f"# {name}", "", sweep.doc + ".", ""]
    for path in files:
        doc = json.loads(path.read_text())
        rows = doc["rows"]
        if not rows or doc.get("sweep") != name:  # empty, or another tool's data kept beside the sweep's
            continue
        png = path.with_suffix(".png")
        section = SECTIONS[sweep.kind](rows, png)
        md += [f"## {rows[0]['device']}", "",
               f"Measured by `{doc['command']}` (Warp {rows[0]['warp']}, commit {rows[0]['commit']}, "
               f"{rows[0]['measured'][:10]}); data: [{path.name}]({path.name}). This page: "
               f"`python -m warpvol bench report {name}`. Frame times exclude the first frame "
               f"(JIT compile and warm-up: {rows[0]['first_frame_ms']:.0f} ms for the first row).", ""]
        if png.exists():
            md += [f"![{name}]({png.name})", ""]
        md += section + [""]
    if sweep.note:
        md += [sweep.note]
    (folder / "README.md").write_text("\n".join(md))
    return folder / "README.md"
