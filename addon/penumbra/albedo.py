"""Per-texel albedo of objects whose diffuse colour comes from a texture or any other node tree.

The solver works with one albedo per face (an image texture's mean, 0.8 grey for a node it cannot read; see
materials.py), which is what the light bounced off a surface needs. What a lightmap shows is albedo x irradiance at
each texel, so for such objects the write-back asks the solver for the irradiance (E / pi) and multiplies it by the
albedo at the same texel. That albedo comes from Cycles' own DIFFUSE bake with only the Color pass, into the
lightmap's UV layout: Cycles evaluates the material exactly as it renders it (image textures through their UV map
and Mapping node, procedural textures, mixes). The Color pass needs no light transport (no bounces); its samples
only spread over the texel, as those of Cycles' full DIFFUSE bake do, so a texel on a texture's edge holds the same
mix of both sides.

Nothing here stays in the .blend: the image nodes, the images and the render settings are put back on every
path, and objects that showed the preview are switched back to it.
"""
import time

import bpy
import numpy as np

from . import compat
from .materials import albedo_varies, bake_batches, bake_targets, image_rgba

# Samples per texel of the Color bake. Cycles' DIFFUSE bake spreads its samples over each texel, so a texel that
# a texture edge crosses holds a mix; at one sample the albedo is the texel centre's alone. On a checkered floor
# (48 texels over 16 squares) against a 1024-spp Cycles bake: 1 sample 1.1 % RMS per texel, 16 samples 0.68 %,
# 64 samples 0.35 % (4 samples: 1.7 %, a noisy mix on the edges). 16 samples cost 2.7 s at 256 x 256 and 20 s at
# 1024 x 1024 for one object on this machine under load (1 sample: about a quarter of that).
# Blender 4.0+ (blue-noise sampling since 4.2) mixes the edges less well at 16: 3.6 % on the same floor in 5.2,
# 0.41 % at 64 (1 sample: 5.7 %), so newer versions take 64.
SAMPLES = 16 if bpy.app.version < (4, 0, 0) else 64

# A texel that Cycles' margin covers but the solver's dilation does not is harmless (it is multiplied by 0);
# the reverse would show black rims, so Cycles' margin reaches a little further than the lightmap's.
EXTRA_MARGIN = 2


def own_materials(ob):
    """The materials `ob` renders with when the preview is off."""
    from .export import _own_materials
    return _own_materials(ob, ob)


def needs_bake(ob):
    """Whether any material of `ob` has an albedo that changes across the surface."""
    return any(albedo_varies(m) for m in own_materials(ob))


def why_not(ob):
    """Why Cycles cannot bake the albedo of `ob` (a slot without a node material), or None."""
    for i, m in enumerate(own_materials(ob) or [None]):
        if m is None or not compat.uses_nodes(m):
            return f"material slot {i + 1} holds no node material"
    return None


class _Settings:
    """The render and bake settings the albedo bake changes, with their values before it."""

    def __init__(self, scene):
        c = scene.cycles
        self.saved = [(scene.render, "engine"), (c, "device"), (c, "samples"), (c, "use_adaptive_sampling"),
                      (c, "use_denoising"), (c, "bake_type"), (c, "max_bounces")]
        self.saved += [(vl.cycles, "use_denoising") for vl in scene.view_layers]
        b = scene.render.bake
        self.saved += [(b, k) for k in ("margin", "margin_type", "use_clear", "target", "use_selected_to_active",
                                        "use_pass_direct", "use_pass_indirect", "use_pass_color")
                       if hasattr(b, k)]
        self.saved = [(s, k, getattr(s, k)) for s, k in self.saved if hasattr(s, k)]

    def restore(self):
        for struct, key, value in reversed(self.saved):
            if getattr(struct, key) != value:
                try:
                    setattr(struct, key, value)
                except (TypeError, ValueError):
                    pass    # an enum this build cannot set back to (no such item): it was never changed


def bake_albedo(scene, view_layer, jobs, margin):
    """Cycles' DIFFUSE Color bake of each object into its lightmap UV map.

    `jobs` maps object name -> (UV map name, resolution). Returns ({name: (res, res, 3) float32 linear albedo,
    rows bottom to top}, seconds spent). Objects that share no material and bake into UV maps of one name are
    baked in one call (one scene sync). Raises RuntimeError if Cycles refuses; nothing is left behind."""
    from .preview import STATE, preview_off, preview_on
    if not jobs:
        return {}, 0.0
    t0 = time.perf_counter()
    settings = _Settings(scene)
    selected = {o.name for o in view_layer.objects if o.select_get(view_layer=view_layer)}
    active = view_layer.objects.active.name if view_layer.objects.active else None
    previewed = [n for n in jobs if bpy.data.objects[n].get(STATE) is not None]
    result = {}
    try:
        # The preview's emissive materials stand in the slots; the bake needs the object's own ones.
        for n in previewed:
            preview_off(bpy.data.objects[n])
        scene.render.engine = "CYCLES"
        c = scene.cycles
        c.device = "CPU"
        c.samples = SAMPLES
        c.use_adaptive_sampling = False
        c.max_bounces = 0        # the Color pass is the albedo where the texel's ray meets the surface
        # Debian's Cycles has no OpenImageDenoise; with denoising on, baking prints errors (facts §0).
        c.use_denoising = False
        for vl in scene.view_layers:
            vl.cycles.use_denoising = False
        uv_of = {name: uv_name for name, (uv_name, res) in jobs.items()}
        for names in bake_batches(uv_of, lambda n: {m.name_full for m in own_materials(bpy.data.objects[n])
                                                     if m is not None}):
            result.update(_bake_batch(scene, view_layer, names, uv_of[names[0]], jobs, margin))
    finally:
        settings.restore()
        for o in view_layer.objects:
            want = o.name in selected
            if o.select_get(view_layer=view_layer) != want:
                o.select_set(want, view_layer=view_layer)
        view_layer.objects.active = view_layer.objects.get(active) if active else None
        for n in previewed:
            ob = bpy.data.objects.get(n)
            if ob is not None and ob.get(STATE) is None:
                preview_on(ob)
    return result, time.perf_counter() - t0


def _bake_batch(scene, view_layer, names, uv_name, jobs, margin):
    sizes = {name: (jobs[name][1], jobs[name][1]) for name in names}
    with bake_targets("Penumbra albedo ", sizes, lambda n: own_materials(bpy.data.objects[n])) as images:
        for o in view_layer.objects:
            if o.select_get(view_layer=view_layer):
                o.select_set(False, view_layer=view_layer)
        for name in names:
            bpy.data.objects[name].select_set(True, view_layer=view_layer)
        view_layer.objects.active = bpy.data.objects[names[0]]
        # The operator bakes the context's scene: name it, for a bake of a scene that is not the active one.
        with bpy.context.temp_override(scene=scene, view_layer=view_layer, active_object=bpy.data.objects[names[0]]):
            r = bpy.ops.object.bake(type="DIFFUSE", pass_filter={"COLOR"}, margin=margin + EXTRA_MARGIN,
                                    margin_type="EXTEND", use_clear=True, target="IMAGE_TEXTURES",
                                    use_selected_to_active=False, uv_layer=uv_name)
        if r != {"FINISHED"}:
            raise RuntimeError(f"Cycles could not bake the albedo of {', '.join(names)} ({r})")
        return {name: np.ascontiguousarray(image_rgba(img)[:, :, :3]) for name, img in images.items()}
