"""Mie phase functions of log-normal water droplets against the Jendersie & d'Eon 2023 fit.

    PYTHONPATH=. .venv/bin/python -m bench.mie_phase [--out results/mie-phase]

For median diameters 5, 10 and 20 um (sigma = 0.1 and 0.3 in ln space) it tabulates the
size-averaged Mie phase function at 650, 550 and 450 nm (``warpvol.scene.mie.mie_table``, what
a scene's ``{type = "mie"}`` loads) and compares its mean with the HG + Draine fit at the
median diameter and with plain HG of the same g. Writes data.json (every number), phase.png
(log p against theta, sigma = 0.1) and README.md (the table) under --out. Host-side numpy only:
no kernel runs, so nothing here depends on the device.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from bench.fingerprint import probe
from bench.harness import REPO, git_commit
from warpvol.scene import mie

DIAMETERS_UM = (5.0, 10.0, 20.0)
SIGMAS = (0.1, 0.3)
PLOT_SIGMA = 0.1


def integral(v: np.ndarray, mu: np.ndarray) -> float:
    """2 pi times the trapezoid integral over the uniform cos grid: exact for the table."""
    return float(2.0 * np.pi * np.trapezoid(v, mu))


def hg(mu: np.ndarray, g: float) -> np.ndarray:
    return mie.hg_draine(mu, mie.HGDraine(g, 0.5, 1.0, 0.0))


def measure(d: float, sigma: float) -> dict:
    mie.mie_table.cache_clear()
    t0 = time.perf_counter()
    t = mie.mie_table(d, sigma)
    cold_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    mie.mie_table(d, sigma)
    cached_s = time.perf_counter() - t0
    mu = t.mu
    p_mie = t.mean / (1.0 + t.norm_error[-1])  # what the kernel reads (tabulate's rescale)
    fit = mie.jendersie_deon(d)
    p_fit = mie.hg_draine(mu, fit)
    p_hg = hg(mu, t.g_mean)
    saved = mie.DX
    mie.DX = saved / 2.0  # the size quadrature with half the step: how far g moves
    try:
        g_half = [mie.mie_phase(np.ones(1), d, sigma, lam)[1] for lam in t.wavelengths_um]
    finally:
        mie.DX = saved
    return {
        "median_diameter_um": d, "sigma": sigma, "refractive_index": t.refractive_index,
        "wavelengths_um": list(t.wavelengths_um), "entries": len(mu), "evaluated_nodes": int(t.evaluated.sum()),
        "size_nodes": [len(mie.size_nodes(d, sigma, lam)[0]) for lam in t.wavelengths_um],
        "table_seconds_cold": cold_s, "table_seconds_cached": cached_s,
        "norm_error_rgb": list(t.norm_error[:3]), "norm_error_mean": t.norm_error[3],
        "g_mie_rgb": list(t.g), "g_mie_mean": t.g_mean, "g_mie_rgb_half_dx": g_half,
        "g_table": integral(p_mie * mu, mu),
        "l1_rgb_to_mean": list(t.l1_to_mean),
        "fit": vars(fit), "g_fit": mie.hg_draine_mean_cosine(fit), "fit_integral": integral(p_fit, mu),
        "l1_mie_vs_fit": integral(np.abs(p_mie - p_fit), mu),
        "l1_mie_vs_hg": integral(np.abs(p_mie - p_hg), mu),
    }


def plot(path: Path, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(DIAMETERS_UM), figsize=(5 * len(DIAMETERS_UM), 4.2), sharey=True)
    for ax, d in zip(axes, DIAMETERS_UM):
        t = mie.mie_table(d, PLOT_SIGMA)
        row = next(r for r in rows if r["median_diameter_um"] == d and r["sigma"] == PLOT_SIGMA)
        deg = np.degrees(np.arccos(t.mu))
        for k, colour in enumerate(("tab:red", "tab:green", "tab:blue")):
            ax.plot(deg, t.values[k], color=colour, lw=0.6, alpha=0.8, label=f"Mie {1000 * t.wavelengths_um[k]:.0f} nm")
        ax.plot(deg, t.mean, color="k", lw=1.2, label=f"Mie mean (g = {t.g_mean:.4f})")
        ax.plot(deg, mie.hg_draine(t.mu, mie.jendersie_deon(d)), "--", color="tab:purple", lw=1.2,
                label=f"HG + Draine fit (g = {row['g_fit']:.4f})")
        ax.plot(deg, hg(t.mu, t.g_mean), ":", color="tab:orange", lw=1.4, label="HG, same g")
        ax.set_yscale("log")
        ax.set_xlim(0, 180)
        ax.set_xlabel("scattering angle theta (degrees)")
        ax.set_title(f"median {d:g} um, sigma = {PLOT_SIGMA:g}")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("p(theta) (1/sr)")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def probe_scene(diameter_um: float, sigma: float) -> dict:
    """A small fog box (homogeneous, albedo 0.9) lit by the sun from behind, with the Mie phase of
    these droplets: its probe renders their forward peak, so a change of the tables moves it."""
    return {"name": f"mie-{diameter_um:g}-{sigma:g}", "background": [0.0, 0.0, 0.0],
            "camera": {"origin": [0.0, 0.0, 3.0], "target": [0.0, 0.0, 0.0], "fov_y": 40.0},
            "lights": [{"type": "directional", "direction": [0.1, -0.2, 1.0], "irradiance": 1.0}],
            "media": [{"type": "homogeneous", "shape": "box", "size": [1.5, 1.5, 1.5], "sigma_t": 1.0, "albedo": 0.9,
                       "phase": {"type": "mie", "median_diameter_um": diameter_um, "sigma": sigma}}]}


def readme(rows: list[dict], command: str) -> str:
    cpu = subprocess.run("lscpu | grep 'Model name'", shell=True, capture_output=True, text=True).stdout.strip()
    lines = [
        "# Mie phase functions of fog droplets vs the Jendersie & d'Eon 2023 HG + Draine fit",
        "",
        f"Command: `{command}`  ",
        f"Machine: {' '.join(cpu.split())}  ",
        f"Date: {datetime.date.today().isoformat()}  ",
        f"warpvol commit: {git_commit()} (plus the working tree this was run from)",
        "",
        "Log-normal water droplets (n = 1.333), phase functions averaged over the sizes with weight",
        "number density x scattering cross-section (miepython), at 650 / 550 / 450 nm; the scene's",
        "table is their mean (`warpvol.scene.mie.mie_table`). The fit is evaluated at the median diameter.",
        "L1 is the integral over the sphere of |p_a - p_b| (0 = equal, 2 = disjoint); g is the mean",
        "cosine (Mie: exact, miepython's g per size averaged like p; fit: closed form). `g half dx` is",
        "the mean of the three wavelengths' g with half the size-quadrature step, i.e. how far the",
        "Mie g moves when the quadrature is refined (Mie resonances are sampled, not resolved).",
        "`norm err` is the trapezoid integral of the table minus 1 before `tabulate` rescales it.",
        "",
        "| median (um) | sigma | entries | g R / G / B | g mean | g half dx | g fit | g fit - g Mie | "
        "L1 Mie vs fit | L1 Mie vs HG(g) | L1 R / G / B to mean | norm err mean (max RGB) | table s (cached) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['median_diameter_um']:g} | {r['sigma']:g} | {r['entries']} | "
            f"{' / '.join(f'{g:.4f}' for g in r['g_mie_rgb'])} | {r['g_mie_mean']:.4f} | "
            f"{np.mean(r['g_mie_rgb_half_dx']):.4f} | {r['g_fit']:.4f} | {r['g_fit'] - r['g_mie_mean']:+.4f} | "
            f"{r['l1_mie_vs_fit']:.3f} | {r['l1_mie_vs_hg']:.3f} | "
            f"{' / '.join(f'{v:.3f}' for v in r['l1_rgb_to_mean'])} | "
            f"{r['norm_error_mean']:.1e} ({max(map(abs, r['norm_error_rgb'])):.1e}) | "
            f"{r['table_seconds_cold']:.1f} ({r['table_seconds_cached'] * 1e6:.0f} us) |")
    lines += ["", "![phase functions](phase.png)", "",
              f"phase.png: sigma = {PLOT_SIGMA:g}; log p against theta in degrees.", ""]
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "results" / "mie-phase"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = "PYTHONPATH=. .venv/bin/python -m bench.mie_phase"
    mie.mie_table(1.0, 0.0)  # load miepython's numba kernels before timing
    rows = [measure(d, s) for d in DIAMETERS_UM for s in SIGMAS]
    for r in rows:  # what bench report --stale renders again: a small fog box with the row's phase function
        table = probe_scene(r["median_diameter_um"], r["sigma"])
        r["probe"] = probe({"params": {"technique": "raymarch", "multiple_scattering": 0}}, table)
    for r in rows:
        print(f"d={r['median_diameter_um']:g} sigma={r['sigma']:g}: g Mie {r['g_mie_mean']:.4f} fit {r['g_fit']:.4f} "
              f"L1 {r['l1_mie_vs_fit']:.3f} norm err {r['norm_error_mean']:.1e}")
    (out / "data.json").write_text(json.dumps({"command": command, "commit": git_commit(), "rows": rows}, indent=1))
    plot(out / "phase.png", rows)
    (out / "README.md").write_text(readme(rows, command))


if __name__ == "__main__":
    main()
