"""Named sweeps, one module per technique: each paper's tables (bench/paper_tables.toml), accuracy
sweeps (error against the reference vs time) and the pipeline's own overhead. ``SWEEPS`` is the
registry, by name, in the order ``python -m warpvol bench --list`` shows."""

from . import (census, depth_impostors, front, illumination_network, light_shafts, multiple, particle_glow, raymarch,
               rbf_propagation, reference)
from .common import PAPER_TABLES, Sweep, row_fps  # noqa: F401  (PAPER_TABLES: the papers' numbers, for scripts)
from .illumination_network import network_scene  # noqa: F401  (bench/test_kernels.py)
from .light_shafts import shafts_scene  # noqa: F401
from .reference import cumulus_scene  # noqa: F401

SWEEPS: dict[str, Sweep] = {s.name: s for s in [
    Sweep("defaults", "the census: every built-in scene with every technique that takes it, at its defaults, at the "
          "scene's own resolution and at 160x120: time per frame and per stage, each over the reference's at 16 spp, "
          "and at 160x120 the error against the physical answer (the reference, all orders of scattering)",
          "reference", "census", census.census_grid, census.census, note=census.CENSUS_NOTE),
    Sweep("depth-impostors", "Umenhoffer & Szirmay-Kalos 2005 figure 5: 8000 particles under one directional light, no blocks and 1600, "
          "800, 400, 40, 20 blocks; a frame of an animated cloud under a moving light at 512x512",
          "depth_impostors", "paper", depth_impostors.impostor_fig5_grid, depth_impostors.impostor_frame, paper=("depth_impostors",),
          figure=row_fps, note=depth_impostors.IMPOSTOR_FIG5_NOTE),
    Sweep("depth-impostors-sweep", "depth_impostors over N (1000, 8000, 64000 particles) and the block size "
          "(1..1000 particles a block): where the fastest block size lies as N grows",
          "depth_impostors", "paper", depth_impostors.impostor_sweep_grid, depth_impostors.impostor_frame),
    Sweep("depth-impostors-accuracy", "depth_impostors against the single-scattering reference: light-pass slices "
          "S = 1..32, impostor resolution 4..64, Fourier terms K = 2..16, the exact light, sky directions 0..64 and the "
          "forward-scattering widening 0.5..4 radii (also against the multiple-scattering reference)",
          "depth_impostors", "accuracy", depth_impostors.impostor_accuracy_grid, depth_impostors.impostor_accuracy),
    Sweep("depth-impostors-objects", "objects in clouds (Umenhoffer & Szirmay-Kalos 2005 section 2.4): a plane through the cloud, depth "
          "impostors against billboards, both against the single-scattering reference",
          "depth_impostors", "accuracy", depth_impostors.impostor_objects_grid, depth_impostors.impostor_objects),
    Sweep("depth-impostors-clipping", "clipping repaired (Umenhoffer & Szirmay-Kalos 2005 section 2.4): 25 large "
          "particles straddling a plane, billboards against depth impostors, each particle shaded as a whole (the paper) "
          "and per pixel along its chord, still and drifting through the plane, "
          "against the single-scattering reference over the seam and over the image, 96x96", "depth_impostors", "table", depth_impostors.impostor_clipping_grid,
          depth_impostors.impostor_clipping, note=depth_impostors.CLIP_NOTE),
    Sweep("depth-impostors-inside", "a camera inside a cloud (Umenhoffer & Szirmay-Kalos 2005): 300 particles "
          "around the eye, four holding it, billboards and depth impostors, each particle shaded as a whole (the "
          "paper) and per pixel along its chord, against the single-scattering reference, 96x72", "depth_impostors",
          "table", depth_impostors.impostor_inside_grid, depth_impostors.impostor_inside,
          note=depth_impostors.INSIDE_NOTE),
    Sweep("particle-glow-figure5", "particle_glow: the glowy-light paper figure 5's density distributions (mu, sigma; A: 2, "
          "0.1; B: 0, 0.1), the defaults (0.5, 0.5), log-normal (cdf 0, the text) and normal (cdf 1, equation 2 as "
          "printed) CDFs, dusty-lamp 320x240", "particle_glow", "table", particle_glow.glow_figure5_grid, particle_glow.glow_figure5),
    Sweep("particle-glow-physics", "particle_glow against the reference on the same homogeneous medium (single and "
          "multiple scattering), beside its direct sample alone, raymarch and light_shafts, dusty-lamp 160x120",
          "particle_glow", "accuracy", particle_glow.glow_physics_grid, particle_glow.glow_physics),
    Sweep("particle-glow-ground-truth", "particle_glow against what it imitates: the reference on explicit particles "
          "drawn from its density texture (three draws, all orders), the glow off, from the nearest particle, from the "
          "two nearest (averaged and summed) and the multiple-scattering lattice in its place; error outside the lamp's "
          "core, mean, grain, glow-room 80x60", "particle_glow", "table", particle_glow.glow_truth_grid,
          particle_glow.glow_truth, note=particle_glow.GT_NOTE),
    Sweep("particle-glow-speed", "particle_glow against the raymarch baseline, 128 steps each, dusty-lamp 640x480, "
          "timed in alternation (the issue's bound: 1.5x)", "particle_glow", "table", particle_glow.glow_speed_grid, particle_glow.glow_speed),
    Sweep("particle-glow-stability", "particle_glow: the frame-to-frame change of a slowly moving camera's image, "
          "the grain fixed in the world (as built) against grain that moves with the screen, and without the glow",
          "particle_glow", "table", particle_glow.glow_stability_grid, particle_glow.glow_stability),
    Sweep("accuracy-vs-time", "every technique that can render a scene family, at a ladder of its quality knob, "
          "against the physical answer (the reference, all orders of scattering, sky included): relative RMSE "
          "against ms per frame, 64x48; Mitsuba 3's volpath (llvm_ad_rgb) beside them where it can export the scene "
          "(homogeneous media)", "reference", "front", front.front_grid, front.front),
    Sweep("multiple-scattering", "the marchers' multiple-scattering lattice (warpvol.scattering) against the physical "
          "answer (the reference, all orders) per scene family: each marcher without it (multiple_scattering = 0, the "
          "paper's model, at its defaults and at four times its quality knob) and with it (the defaults); raymarch's "
          "lattice doubled (n, D) = (4, 8) .. (24, 48) beside the reference's error over its time on a fog box and "
          "smoke-grid, 64x48", "raymarch", "multiple", multiple.ms_grid, multiple.ms_measure,
          note=multiple.MS_NOTE),
    Sweep("raymarch-accuracy", "raymarch: relative RMSE against the single-scattering reference vs ms per frame, "
          "sweeping steps (= shadow_steps) and the baked light-volume size (0 = marched shadow rays)",
          "raymarch", "accuracy", raymarch.raymarch_grid, raymarch.raymarch_accuracy),
    Sweep("pipeline-overhead", "the pipeline's bookkeeping per frame (stage cache checks, timing, the Frame)",
          "raymarch", "overhead", raymarch.overhead_grid, raymarch.overhead),
    Sweep("light-shafts", "Tóth & Umenhoffer 2009 section 5: no scattering / scattering / scattering + interleaved (N = 64, "
          "M = 4), colonnade-shafts 800x600, camera and light moving (shadow maps, surface pass, march, block sums "
          "every frame; the BVH of the static geometry cached)",
          "light_shafts", "paper", light_shafts.shafts_table_grid, light_shafts.shafts_frame, paper=("light_shafts",),
          figure=light_shafts.shafts_paper_fps),
    Sweep("light-shafts-sweep", "light_shafts frame time over N (steps), M (block) and shadow-map resolution, "
          "colonnade-shafts 800x600, camera and light moving",
          "light_shafts", "paper", light_shafts.shafts_sweep_grid, light_shafts.shafts_frame),
    Sweep("light-shafts-speedup", "light_shafts: the march stage's speed-up from M x M interleaving over the same N "
          "without it, both timed in alternation (target >= 0.7 M^2), colonnade-shafts 800x600",
          "light_shafts", "speedup", light_shafts.shafts_speedup_grid, light_shafts.shafts_speedup),
    Sweep("light-shafts-edges", "light_shafts: the error interleaving leaves at depth discontinuities (mean |interleaved"
          " - per-pixel N = 64| / mean, near depth jumps and elsewhere), with the paper's block sum (edges = 0) and the "
          "depth-aware one (edges = 1), colonnade-shafts 800x600",
          "light_shafts", "edges", light_shafts.shafts_edges_grid, light_shafts.shafts_edges),
    Sweep("light-shafts-accuracy", "light_shafts: relative RMSE against the single-scattering reference (and the "
          "1024-step raymarch with exact shadow rays) vs ms per frame, over N, M and shadow-map resolution, "
          "colonnade-shafts 320x240",
          "light_shafts", "accuracy", light_shafts.shafts_accuracy_grid, light_shafts.shafts_accuracy),
    Sweep("rbf-table2", "Giroud & Biri 2011 Table 2: grid 15..40, 1 light precomputed (P: only the march runs) and 1/2/4/8 "
          "dynamic lights (medium and lights change every frame), rbf-thick-fog's 1000 RBFs, 800x600",
          "rbf_propagation", "paper", rbf_propagation.table2_grid, rbf_propagation.table2, paper=("rbf_propagation", "table2"),
          figure=rbf_propagation.table2_fps, note=rbf_propagation.TABLE2_NOTE),
    Sweep("rbf-table3", "Giroud & Biri 2011 Table 3: 1..27 000 RBFs at grid 20, one light, dynamic (all stages) and static "
          "(only the march), 800x600",
          "rbf_propagation", "paper", rbf_propagation.table3_grid, rbf_propagation.table3, paper=("rbf_propagation", "table3"),
          figure=rbf_propagation.table3_fps),
    Sweep("rbf-propagation-rules", "Giroud & Biri 2011 equation 6 as printed (rule 0) and corrected (rule 1), wavefront or "
          "whole-grid sweeps, against optical depth marched from each cell centre to each light (rbf-cornell)",
          "rbf_propagation", "rules", rbf_propagation.rules_grid, rbf_propagation.rules),
    Sweep("rbf-scaling", "rbf_propagation: propagation time against cells x sweeps and march time against pixels x "
          "steps, with the fitted exponents",
          "rbf_propagation", "scaling", rbf_propagation.scaling_grid, rbf_propagation.scaling),
    Sweep("rbf-shadows", "rbf_propagation's propagated shadows (Giroud & Biri 2011): a dense puff between a point light "
          "and a layer of puffs over a floor, the error in its shadow and over the image against raymarched shadows, "
          "and the per-cell optical-depth error, as the grid grows (scenes/rbf-shadows.toml, 96x72)",
          "rbf_propagation", "table", rbf_propagation.shadows_grid, rbf_propagation.shadows,
          note=rbf_propagation.SHADOWS_NOTE),
    Sweep("rbf-accuracy", "rbf_propagation: relative RMSE against the single-scattering reference vs ms per frame, "
          "over grid size and march steps, rbf-cornell 80x60",
          "rbf_propagation", "accuracy", rbf_propagation.rbf_accuracy_grid, rbf_propagation.rbf_accuracy),
    Sweep("illumination-network", "Szirmay-Kalos et al. 2005 section 4: 1024 and 512 particles at 128 directions, one iteration "
          "per frame, lights and camera moving, 512x512 (direct light, emission, one iteration, splat), HG g = 0 (isotropic)",
          "illumination_network", "paper", illumination_network.network_table_grid, illumination_network.network_frame, paper=("illumination_network",),
          figure=row_fps),
    Sweep("illumination-network-sweep", "illumination_network over N (256..16384 particles) and D (32..512 "
          "directions), window by the paper's rule unless given: frame, one iteration (with its multiply-add rate) "
          "and the visibility-network build, HG g = 0 (isotropic)",
          "illumination_network", "paper", illumination_network.network_sweep_grid, illumination_network.network_frame),
    Sweep("illumination-network-convergence", "Szirmay-Kalos et al. 2005 figure 6: change per iteration and error to the converged "
          "solution, iterating from zero, 1024 particles, 128 directions, albedo 0.9 and 0.99, HG g = 0 (isotropic), the "
          "window by the paper's rule (window=0, M = 70), M = 16, and M from 4 particles per column (column=4)",
          "illumination_network", "convergence", illumination_network.convergence_grid, illumination_network.convergence),
    Sweep("illumination-network-anisotropy", "illumination_network against the multiple-scattering reference on "
          "forward-scattering particles (HG g = 0, 0.6, 0.9): the phase matrix as tabulated (phase_norm=0, the paper's) "
          "or scaled doubly stochastic (phase_norm=1, the default), D = 64 and 256, 1024 particles, 48x48; and under a "
          "black sky (sky=0), the suns alone, at the paper's window and at windows 8 and 4 (and these under the sky)",
          "illumination_network", "accuracy", illumination_network.anisotropy_grid, illumination_network.anisotropy),
    Sweep("illumination-network-accuracy", "illumination_network: converged image against the multiple-scattering "
          "reference vs ms per frame (lights moving), over N, D and the window M (given, the paper's rule, or from "
          "particles per column), HG g = 0 (isotropic), 48x48",
          "illumination_network", "accuracy", illumination_network.network_accuracy_grid, illumination_network.network_accuracy),
    Sweep("illumination-network-animated", "beyond Szirmay-Kalos et al. 2005: a drifting cloud with the visibility network "
          "re-peeled k directions a frame (0: all), error against the full rebuild per frame and frame time, HG g = 0 "
          "(isotropic)",
          "illumination_network", "animated", illumination_network.animated_grid, illumination_network.animated),
    Sweep("illumination-network-lightpass", "the shared light pass (media/lightpass.py) in illumination_network: "
          "exact transmittance (BVH) at 4, 16, 64 points a sphere, depth slices S = 4..64 and Fourier terms "
          "K = 4..32 at 16 points; the direct light per particle against the exact sphere mean, and the image, HG g = 0 "
          "(isotropic)",
          "illumination_network", "lightpass", illumination_network.lightpass_grid, illumination_network.lightpass_accuracy),
    Sweep("illumination-network-lightpass-scaling", "the shared light pass as particles get finer (1024..8192 "
          "particles, radius ~ n^(-1/3), sigma_t r fixed, both suns turning 3 degrees a frame): the direct stage's ms "
          "and the map it ended at (texels, refinements, error, fallback to exact), HG g = 0 (isotropic)",
          "illumination_network", "table", illumination_network.lightpass_scaling_grid, illumination_network.lightpass_scaling),
    Sweep("illumination-network-albedo", "Szirmay-Kalos et al. 2005's bound: the error of one step eps grows to at most "
          "eps / (1 - a); single- and multiple-scattering RMSE against the reference at albedo 0.5, 0.8, 0.95, HG g = 0 "
          "(isotropic)",
          "illumination_network", "bound", illumination_network.albedo_grid, illumination_network.albedo_bound),
    Sweep("illumination-network-lights", "Szirmay-Kalos et al. 2005's claim that the speed hardly depends on the number "
          "of lights or the sky: 1024 particles, D = 128, one iteration a frame, 1..16 directional lights turning every "
          "frame, under a black and a blue sky, 256x256, HG g = 0 (isotropic)",
          "illumination_network", "table", illumination_network.lights_grid, illumination_network.lights_cost),
    Sweep("light-shafts-equal-time", "Tóth & Umenhoffer 2009's claim that interleaving keeps the quality at a "
          "fraction of the cost, at equal frame time: N samples over M x M pixels (M = 1, 2, 4, 8; the paper's block "
          "sum and the depth-aware one) against light_shafts' own converged image, over the image and near depth jumps "
          "apart, colonnade-shafts 320x240",
          "light_shafts", "table", light_shafts.shafts_equal_time_grid, light_shafts.shafts_equal_time),
    Sweep("reference-speed", "the reference path tracer: camera paths per second (and per core) on the built-in "
          "scenes at 160x120, 64 spp, and a 400-sphere cumulus at 80x60, 4096 spp, all orders of scattering; "
          "Mitsuba 3 volpath timed on the same scene where it can render it",
          "reference", "speed", reference.speed_grid, reference.speed),
]}
