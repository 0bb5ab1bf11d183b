"""Depth impostors: particle clouds built of blocks, light slices, objects inside clouds.

Umenhoffer & Szirmay-Kalos, "Real-Time Rendering of Cloudy Natural Phenomena with
Hierarchical Depth Impostors", Eurographics 2005 short presentations (8000 particles, one directional light, 8 FPS without blocks and 200 FPS with 40
blocks on a GeForce 6800 GT). A cloud of N particles is built of N / b copies (instances) of
one block of b particles, so a frame renders the block once (b) and then its instances
(N / b) instead of N particles. Single scattering of the scene's lights. Stages:

* ``blocks`` (reads the medium): the particles to the device, and the blocks. A medium made
  by ``generator = {kind = "blocks", ...}`` (``block_size`` b > 1) is K instances of one
  template block: the block's particles about its centroid, and the K centroids. Any other
  particle medium is grouped into blocks of ``cluster`` particles, neighbours along a
  Morton curve (each group its own template and one instance); ``cluster = 1`` (default)
  makes every particle an instance of a one-particle template (the paper's "no blocks").
* ``light`` (reads the lights): the shared light pass (media/lightpass.py) over the cloud:
  per light, the opacity accumulated up to S depths (the paper's light slices, S = 4 in one
  RGBA texture; here ``slices``), read at any point by interpolating between the two
  slices that enclose it. Directional lights get an orthographic pass, point and spot
  lights a perspective one (a cube inside the cloud). ``light_pass = 2``: a Fourier
  opacity map of ``light_terms`` terms instead (Jansen and Bavoil 2010); 0: exact. The sky
  (the scene's background, the paper's "sky color" in figure 2) is light too: from
  ``sky_samples`` directions over the sphere (``upload.sky_lights``), each with its own
  light pass on a quarter of the sun's texels (sky light is soft), exact where ``light_pass`` = 0;
  not built for a black sky. Where every particle is in a block of several
  (``light_blocks`` = 1), a directional light's map (the sun's, the sky's) is made block by
  block, the paper's b + N / b: each template rendered once from the light into a light
  impostor (per cell: the chords' total length and the mean and variance of their depth),
  and each instance splatted from it into the slices, its chords through a texel merged
  into one segment of the same mean and spread. Point and spot lights stay per particle.
* ``templates``: whether the blocks' templates changed; when an animation only moves the
  instances, the impostors stay cached.
* ``impostors`` (reads the camera): each template block's depth impostor for the camera
  direction: T x T texels over the block's bounding disc (``impostor_res``; 0: T = 3 R / r,
  a texel two thirds of a particle radius r across the block's radius R, and no finer than
  two pixels of the largest projected block, D / 2; ``impostor_detail`` scales both), per texel the
  total opacity 1 - prod(1 - alpha_j) = 1 - exp(-sum sigma_t chord_j) (RGB; each sphere's
  chord analytic), the front and back depths (min entry, max exit, from the block's
  centre), and the depth it is shaded at (the chords' centres weighted by what each sends
  toward the viewer: a thick texel is seen at its front). b x T^2 work, once per template, not per instance. A one-particle template needs
  no texture: its opacity along a pixel ray is the sphere's own chord.
* ``shade`` (reads the camera): what each instance's texel scatters toward the camera:
  albedo x sum over lights of p(theta) E T_light, T_light read from the light pass at the
  texel's shading depth (the block's own particles toward the light included: its
  self-shadowing), plus the sky's albedo L_sky sum_k p_k T_k / sum_k p_k. ``widen`` > 0: the
  paper's forward-scattering widening (``particle_light_transmittance``). A one-particle instance: its irradiance averaged over the sphere at
  ``light_samples`` points (``LightPass.direct``).
* ``surfaces`` (reads the surfaces, camera): per pixel the nearest surface (its depth: the
  paper's depth buffer) and its colour lit through the light pass (the cloud's shadow) and
  past the other surfaces.
* ``gather`` (reads the camera, background): instances listed per 8 x 8 pixel tile near
  to far (``bin_spheres``, by their bounding spheres) and composited front to back: an
  instance adds T alpha L and scales T by 1 - alpha; a block's impostor is read in its plane
  within its reach R of its centre, where its spheres are. Objects in clouds (section 2.4): where the surface depth falls in
  a block's [front, back] interval along the pixel ray, its optical depth is scaled by the
  fraction of the interval in front of the surface (uniform density in the block; for a
  one-particle instance the chord is cut exactly). ``object_depth = 0`` is the billboard
  the paper fixes: a block stands at its centre plane, wholly in front of or behind the
  surface. The background (or the surface) shows through.

With ``multiple_scattering`` = n > 0 (the default) the light scattered more than once is
added too: solved on an n^3 lattice of ``ms_directions`` directions (``warpvol.scattering``,
stages ``multiple`` and ``multiple_view``) and read at each shaded texel and one-particle instance as albedo R(x); 0 is the paper's model.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ... import device as dev
from ...geometry.camera import camera_view
from ...geometry.tiles import SPHERE_TILE, bin_spheres
from ...media.lightpass import REPRESENTATIONS, LightPass
from ...media.particles import BlockCloud, ParticleBuffers
from ...physics.constants import INF
from ...physics.lights import Emitter
from ...physics.phase import phase_fn, phase_struct
from ...pipeline import FLAG, Bias, Quality, Setting, Stage, Technique
from ...scattering import BIASES as MS_BIASES
from ...scattering import SETTINGS as MS_SETTINGS
from ...scattering import MultipleScattering
from ...scattering import check_settings as check_ms_settings
from ...scattering import leaves_out as ms_leaves_out
from ...upload import SceneUploads, check_particle_scene, particle_buffers, pinhole, sky_lights
from .blocks import BlockLayout, build_blocks, view_res
from .kernels import (CloudLight, Impostors, Shaded, SurfaceLayer, gather, make_impostors, scattered_particles,
                      shade_particles, shade_surfaces, shade_texels)

NAME = "depth_impostors"
LIGHT_WORK = 4.0  # a texel's light-map read and phase for one light, in simple per-pixel threads (device.launch)
SETTINGS = {
    "impostor_res": Setting(0, 0, 512, "texels across a block's depth impostor (T x T); 0: from the block's size "
                                       "(``impostor_detail``)"),
    "impostor_detail": Setting(1.0, 0.125, 16.0, "with impostor_res = 0, T = this x min(3 R / r, D / 2): a texel two "
                                                 "thirds of a particle radius r across (R the block's radius) and no "
                                                 "finer than two pixels of its largest projected diameter D"),
    "cluster": Setting(1, 1, 100000, "a cloud not built of blocks is grouped into blocks of this many particles "
                                     "(neighbours in Morton order); 1: every particle on its own"),
    "slices": Setting(4, 1, 1024, "light-pass depth slices S (the paper: 4, in one RGBA texture)"),
    "light_pass": Setting(1, 0, 2, "0 exact transmittance (BVH ray queries; the sky's too), 1 depth slices, "
                                    "2 Fourier opacity map (the sky: depth slices for 1 and 2)",
                          names=REPRESENTATIONS),
    "light_terms": Setting(8, 1, 256, "Fourier terms K (light_pass = 2)"),
    "light_texels": Setting(0, 0, 1024, "light-pass texels per face side; 0: 4 R / r (half a median radius)"),
    "light_blocks": Setting(1, 0, 1, "1: a cloud built of blocks is splatted into the light pass block by block, "
                                     "from one light impostor per template (section 2, b + N / b work; directional "
                                     "lights and the sky); 0: particle by particle", names=FLAG),
    "light_samples": Setting(4, 1, 1024, "points of a one-particle instance whose light is averaged"),
    "sky_samples": Setting(8, 0, 256, "directions the sky's light (the scene's background) is gathered from, each "
                                       "through its own coarse light pass; 0: no sky light"),
    "widen": Setting(0.0, 0.0, 16.0, "forward-scattering widening (section 2.3): the light at a texel averaged with a "
                                     "ring this many median particle radii across, weighted by the phase function; "
                                     "0: off"),
    "particle_shading": Setting(0, 0, 1, "how a one-particle instance is shaded: sphere, one radiance a particle (its "
                                         "irradiance averaged over light_samples points of the sphere: the paper's "
                                         "particles); chord, each pixel's visible chord through it at the depth its "
                                         "light comes from (large or thick particles, whose lit and shadowed sides "
                                         "differ, and a camera among them)", names=("sphere", "chord")),
    "object_depth": Setting(1, 0, 1, "1: depth impostors (a block's opacity cut where a surface lies inside its "
                                     "depth interval); 0: billboards (a block at its centre plane, as the paper fixes)",
                                     names=("billboards", "impostors")),
    **MS_SETTINGS,
}



class DepthImpostors(Technique):
    """Umenhoffer & Szirmay-Kalos 2005: depth impostors of particle blocks, light slices, objects in clouds."""

    NAME = NAME
    EXAMPLES = ("particle-cloud",)
    TINY = {"impostor_res": 4, "slices": 2, "light_samples": 2}
    CENSUS = ("particle-cloud", {})
    SETTINGS = SETTINGS
    QUALITY = Quality(knob="slices", start=2, top=512, order=1, biases=(
        Bias("light_pass", exact=0), Bias("impostor_detail", factor=4, order=1),
        Bias("light_samples", factor=4, order=1), Bias("sky_samples", factor=4, order=1, when="sky"), *MS_BIASES))
    LEAVES_OUT = ()

    def __init__(self, scene, device, settings, progress=False):
        super().__init__(scene, device, settings, progress)
        check_particle_scene(NAME, scene)
        self.uploads = SceneUploads(self, medium=False)
        self.multiple = MultipleScattering.over(self, self.uploads, media=False)
        self._cloud: ParticleBuffers | None = None
        self._template_key: tuple | None = None  # what the impostors were made from
        self.layout: BlockLayout | None = None  # the blocks: templates and their instances
        self.phase = self.table = None
        self.light_pass: LightPass | None = None
        self.sky_pass: LightPass | None = None  # the sky's directions (None: a black sky, or sky_samples = 0)
        self.sky = None
        self.impostors: Impostors | None = None
        self.texel_radiance = self.particle_radiance = None
        self.surf_depth = self.surf_colour = None
        self.image = None
        self.gather_tests = 0  # (pixel, instance) pairs the gather looks at: its tiles' lists x their pixels

    def check_settings(self, settings):
        check_ms_settings(NAME, settings)

    def leaves_out(self) -> list[str]:
        shadows = (["the surfaces' shadows on the cloud (the light pass holds the particles alone)"]
                   if self.scene.surfaces and self.scene.lights else [])
        return [*ms_leaves_out(self.settings), *super().leaves_out(), *shadows]

    def stages(self):
        surfaces = bool(self.scene.surfaces)
        return self.uploads.stages() + [
            *self.multiple.stages(after=("surfaces", "lights")),
            Stage("blocks", self._blocks, reads=("medium",),
                  settings=("impostor_res", "impostor_detail", "cluster", "light_pass")),
            Stage("light", self._light, reads=("lights", "background"),
                  settings=("slices", "light_pass", "light_terms", "light_texels", "light_samples", "sky_samples",
                            "light_blocks"),
                  after=("blocks", "lights")),
            Stage("templates", self._templates, after=("blocks",)),
            Stage("impostors", self._impostors, reads=("camera",), settings=("impostor_detail", "impostor_res"),
                  after=("templates",)),
            Stage("shade", self._shade, reads=("camera",),
                  settings=("widen", "multiple_scattering", "light_samples", "sky_samples", "particle_shading"),
                  after=("light", "impostors", "multiple_view")),
            Stage("surfaces_lit", self._surfaces_lit, reads=("camera",), after=("light", "surfaces"),
                  needed=surfaces),
            Stage("gather", self._gather, reads=("camera", "background"),
                  settings=("object_depth", "particle_shading", "widen", "multiple_scattering", "sky_samples"),
                  after=("shade", "surfaces_lit") if surfaces else ("shade",)),
        ]

    # --- stages -------------------------------------------------------------------------

    def _blocks(self):
        """The particles to the device, and the cloud as instances of template blocks (``blocks.build_blocks``)."""
        s = self.settings
        self.layout = build_blocks(self.scene.media, s["cluster"], s["impostor_res"], s["impostor_detail"],
                                   self.device)
        self._cloud = particle_buffers(self.scene.media, self.device, hash_grid=False, bvh=s["light_pass"] == 0)
        self.phase, table = phase_struct(self.scene.media[0].phase)
        self.table = wp.array(table if len(table) else np.zeros(1, np.float32), dtype=float, device=self.device)

    def _templates(self) -> bool:
        """Whether the templates changed: an animation that only moves the instances leaves the
        impostors as they are (returns False, so the impostors stage stays cached). Offsets are
        compared to 1e-6 of the block's size: moving a block in float32 re-rounds them."""
        B = self.layout.blocks
        exact = b"".join(a.numpy().tobytes() for a in (B.first, B.count, B.radius, B.sigma_t, B.texel0))
        exact += np.int64(B.res).tobytes()
        offsets = B.offsets.numpy().astype(np.float64)
        old = self._template_key
        same = (old is not None and old[0] == exact and old[1].shape == offsets.shape
                and np.allclose(old[1], offsets, rtol=0.0, atol=1e-6 * max(float(np.abs(offsets).max()), 1e-12)))
        if not same:
            self._template_key = (exact, offsets)
        return not same

    def _light(self):
        s, layout = self.settings, self.layout
        self.light_pass = LightPass(self.device, REPRESENTATIONS[s["light_pass"]], slices=s["slices"],
                                    terms=s["light_terms"], texels=s["light_texels"])
        blocks = None  # the block light pass: where every particle is in a block of several
        if s["light_blocks"] and layout.n_instances and layout.n_textured == layout.n_instances:
            blocks = BlockCloud(layout.blocks, layout.reach_t, layout.n_instances)
        self.light_pass.build(self._cloud, self.uploads.lights, s["light_samples"], blocks)
        self.sky = sky_lights(self.scene.background, s["sky_samples"], self.device)
        self.sky_pass = None
        if self.sky is not None:  # soft light: slices on a quarter of the sun's texels; exact with the sun's
            self.sky_pass = LightPass(self.device, "exact" if s["light_pass"] == 0 else "slices", slices=s["slices"],
                                      texels=max(16, (self.light_pass.M or 64) // 4))
            self.sky_pass.build(self._cloud, self.sky, s["light_samples"], blocks)

    def _impostors(self):
        layout = self.layout
        pc = pinhole(self.scene.camera)  # the camera's frame, right and up scaled by the field of view
        imp = Impostors()
        imp.fwd, imp.right, imp.up = pc.forward, wp.normalize(pc.right), wp.normalize(pc.up)
        n = max(layout.texels, 1)
        imp.alpha = wp.zeros(n, dtype=wp.vec3, device=self.device)
        imp.front = wp.zeros(n, dtype=float, device=self.device)
        imp.back = wp.zeros(n, dtype=float, device=self.device)
        imp.mid = wp.zeros(n, dtype=float, device=self.device)
        imp.res = view_res(layout, self.scene.camera, self.settings["impostor_res"], self.settings["impostor_detail"])
        if layout.texels:
            # a texel tests its ray against the block's b spheres, and each sphere it meets against the
            # others in front: split over the cores by that work, not by the texel count
            dev.launch(make_impostors, layout.textured_t.shape[0] * imp.res * imp.res,
                       [layout.blocks, layout.reach_t, imp, layout.textured_t], self.device, work=layout.texel_work)
        self.impostors = imp

    def _sky_args(self):
        """The sky's map and directions for a kernel (an empty array when there is no sky)."""
        if self.sky is None:
            return self.light_pass.map, wp.empty(0, dtype=Emitter, device=self.device)
        return self.sky_pass.map, self.sky

    def _cloud_light(self) -> CloudLight:
        cl = CloudLight()
        cl.light_map, cl.lights, cl.particles = self.light_pass.map, self.uploads.lights, self._cloud.struct
        cl.sky_map, cl.sky = self._sky_args()
        return cl

    def _widen(self) -> float:
        """The forward-scattering widening's distance: ``widen`` median particle radii."""
        radii = self._cloud.radius
        return self.settings["widen"] * (float(np.median(radii)) if len(radii) else 0.0)

    def _shade(self):
        device, layout = self.device, self.layout
        n_textured, n_instances = layout.n_textured, layout.n_instances
        eye = wp.vec3(*self.scene.camera.origin)
        # the layout's texels a side per textured instance (Shaded.first); the launch covers this view's
        self.texel_radiance = wp.zeros(max(n_textured * layout.blocks.res ** 2, 1), dtype=wp.vec3, device=device)
        self.particle_radiance = wp.zeros(max(n_instances, 1), dtype=wp.vec3, device=device)
        _, sky = self._sky_args()
        ms = self.multiple.struct()
        if ms.lat.n > 0 and not self.settings["particle_shading"]:  # chord: read per pixel in the gather
            dev.launch(scattered_particles, n_instances, [layout.blocks, ms, self.particle_radiance], device)
        if not len(self.scene.lights) and not sky.shape[0] and ms.lat.n == 0:
            return
        if n_textured:
            res = self.impostors.res
            dev.launch(shade_texels, n_textured * res * res,
                       [layout.blocks, self.impostors, self._cloud_light(), phase_fn(self.phase, self.table), eye,
                        self._widen(), ms, layout.textured, self.texel_radiance], device,
                       work=LIGHT_WORK * (len(self.scene.lights) + sky.shape[0]))
        if n_instances > n_textured and not self.settings["particle_shading"]:
            n = self._cloud.struct.centres.shape[0]
            for lights, lp, is_sky in ((self.uploads.lights, self.light_pass, 0), (sky, self.sky_pass, 1)):
                L = lights.shape[0]
                if not L:
                    continue
                direct = wp.zeros(n * L, dtype=wp.vec3, device=device)
                travel = wp.zeros(n * L, dtype=wp.vec3, device=device)
                lp.direct(self._cloud, lights, self.settings["light_samples"], direct, travel)
                dev.launch(shade_particles, n_instances, [layout.blocks, direct, travel, L, layout.particle_of,
                                                          phase_fn(self.phase, self.table), eye, is_sky,
                                                          self.particle_radiance], device)

    def _surfaces_lit(self):
        cam = self.scene.camera
        n = cam.width * cam.height
        self.surf_depth = wp.empty(n, dtype=float, device=self.device)
        self.surf_colour = wp.empty(n, dtype=wp.vec3, device=self.device)
        dev.launch(shade_surfaces, n, [camera_view(pinhole(cam)), self.uploads.surfaces, self._cloud_light(),
                                       self.surf_depth, self.surf_colour], self.device)

    def _gather(self):
        cam, device, layout = self.scene.camera, self.device, self.layout
        n = cam.width * cam.height
        view = camera_view(pinhole(cam))
        if not self.scene.surfaces:
            self.surf_depth = wp.full(n, INF, dtype=float, device=device)
            self.surf_colour = wp.zeros(n, dtype=wp.vec3, device=device)
        centres, reach = layout.centres, layout.reach
        # a textured instance is read in its plane within its reach R of the centre (its
        # spheres lie there; ``gather`` cuts the bilinear lookup's smear beyond R): a disc
        # inside the sphere of radius R, so the sphere's tiles hold it
        eye = np.asarray(cam.origin, np.float64)
        z_far = float(np.max(np.linalg.norm(centres - eye, axis=1) + reach)) if len(centres) else 1.0
        tl = bin_spheres(view, layout.blocks.centre, wp.array(reach.astype(np.float32), dtype=float, device=device),
                         z_far, device)
        self.gather_tests = (tl.values.shape[0] // 2) * SPHERE_TILE * SPHERE_TILE
        self.image = wp.empty(n, dtype=wp.vec3, device=device)
        shaded = Shaded()
        shaded.texels, shaded.first, shaded.particles = self.texel_radiance, layout.first, self.particle_radiance
        shaded.chord = int(self.settings["particle_shading"])
        shaded.cl, shaded.pf, shaded.ms = self._cloud_light(), phase_fn(self.phase, self.table), self.multiple.struct()
        shaded.widen = self._widen()
        surf = SurfaceLayer()
        surf.depth, surf.colour, surf.object_depth = self.surf_depth, self.surf_colour, self.settings["object_depth"]
        per = dev.per_thread(device)
        dev.launch(gather, dev.groups(n, per), [per, view, layout.blocks, self.impostors, tl, shaded, surf,
                                                wp.vec3(*self.scene.background), self.image],
                   device, min_split=dev.MIN_SPLIT // per)

    def output(self):
        return self.image

    def diagnostics(self) -> dict:
        """``instances``: how many block instances; ``block_centres`` (instances x 3) and
        ``block_reach`` (instances): each one's centre and bounding radius, world units;
        ``light_texels``: the light pass's texels per face side (0 before it is built);
        ``light_refined``: how often its map was refined to meet its tolerance;
        ``light_fell_back``: whether it fell back to exact transmittance;
        ``light_template_texels``: texels a side of each template's light impostor (0: the
        light pass splatted particle by particle); ``impostor_res``: texels a side of the
        camera impostors in this view (``blocks.view_res``); ``gather_tests``: the (pixel, instance)
        pairs the gather looks at (each tile's list times its pixels)."""
        blocks = self.layout.blocks
        return {"instances": self.layout.n_instances, "block_centres": blocks.centre.numpy(),
                "block_reach": blocks.reach.numpy(),
                "light_texels": self.light_pass.M if self.light_pass is not None else 0,
                "light_refined": len(self.light_pass.refined) if self.light_pass is not None else 0,
                "light_fell_back": bool(self.light_pass is not None and self.light_pass.fell_back),
                "light_template_texels": self.light_pass.template_texels if self.light_pass is not None else 0,
                "impostor_res": self.impostors.res if self.impostors is not None and self.layout.texels else 0,
                "gather_tests": self.gather_tests}

    def arrays(self, for_view: bool = False, resolution: int = 128) -> dict:
        """The instances (centres, bounding radii), the first textured template's impostor
        layers (opacity, front and back depth; T x T) with the frame they face and the
        instance that shows them, and the light pass's faces and slices."""
        T = self.impostors.res if self.impostors is not None else 0
        layout = self.layout
        out = {"instances": layout.blocks.centre.numpy(), "instance_reach": layout.blocks.reach.numpy()}
        if layout.texels and self.impostors is not None:
            imp = self.impostors
            out.update(impostor_alpha=imp.alpha.numpy()[:T * T].reshape(T, T, 3),
                       impostor_front=imp.front.numpy()[:T * T].reshape(T, T),
                       impostor_back=imp.back.numpy()[:T * T].reshape(T, T),
                       impostor_frame=np.array([list(imp.fwd), list(imp.right), list(imp.up)], np.float32),
                       impostor_instance=int(layout.textured.numpy()[0]) if layout.n_textured else -1)
        if self.light_pass is not None:
            out["light_texels"] = self.light_pass.M
            layers = self.light_pass.layers()
            out["light_faces"] = layers["faces"]
            if "slices" in layers:
                out["light_slices"] = layers["slices"]
        return out


TECHNIQUE = DepthImpostors
