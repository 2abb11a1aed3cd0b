"""Comparison of a Penumbra bake with Cycles path tracing, in camera space and in lightmap space.

`compare_cycles(scene, samples=256, out_dir=None)` renders the scene camera twice with Cycles: the path-traced
reference (denoising off, many bounces, clamping off) and the bake shown through `preview`. It writes both as
EXR, a false-colour relative-difference map and a side-by-side PNG, and returns error figures over the pixels
that show neither an emitter nor the background. With `space="LIGHTMAP"` the reference is Cycles' DIFFUSE bake
(Direct + Indirect + Color) into each object's own lightmap UV map, compared texel by texel and per face.

The reference is made of two half-sample passes with different seeds. Their half difference has the same
variance as the noise of their mean, so the same figures computed on it are the reference's own noise, reported
beside the error. The noise adds in quadrature to the error, so `relative_rms_corrected` removes it.

Every render setting, view-layer flag, the selection, the active object and the preview state are put back
afterwards, whether the comparison succeeds or fails.
"""
import math
import os
import shutil
import tempfile
import time

import bpy
import numpy as np

from . import compat
from .materials import bake_batches, bake_targets, image_rgba, parse_material
from .preview import preview_off, preview_on, set_preview
from .world_map import read_float_image
from .writeback import baked_state

LUMA = np.array([0.2126, 0.7152, 0.0722])


# ---------------------------------------------------------------------------------------------- state

# Enums with no items on this build (no OIDN): reading them only prints warnings, and nothing here sets them.
_SKIP = {"denoiser", "preview_denoiser"}


def _rna_values(struct):
    vals = {}
    for p in struct.bl_rna.properties:
        if p.is_readonly or p.identifier in _SKIP or p.type not in {"BOOLEAN", "INT", "FLOAT", "STRING", "ENUM"}:
            continue
        try:
            v = getattr(struct, p.identifier)
        except (AttributeError, TypeError):
            continue
        vals[p.identifier] = tuple(v) if getattr(p, "is_array", False) or isinstance(v, set) else v
    return vals


def _rna_restore(struct, vals):
    for k, v in vals.items():
        try:
            cur = getattr(struct, k)
            cur = tuple(cur) if not isinstance(cur, (str, int, float, bool)) and hasattr(cur, "__iter__") else cur
            if cur != v:
                setattr(struct, k, set(v) if isinstance(getattr(struct, k), set) else v)
        except (AttributeError, TypeError, ValueError):
            # Some enums (e.g. an empty denoiser list on builds without OIDN) refuse even their own value.
            pass


class _SceneState:
    """Render and bake settings, view-layer passes, selection, active object and preview state."""

    def __init__(self, scene):
        self.scene = scene
        self.structs = [scene.render, scene.render.image_settings, scene.render.bake, scene.cycles,
                        scene.view_settings]
        for vl in scene.view_layers:
            self.structs += [vl, vl.cycles]
        self.values = [_rna_values(s) for s in self.structs]
        self.camera = scene.camera
        vl = bpy.context.view_layer
        self.vl = vl
        self.selected = [o.name for o in vl.objects if o.select_get()]
        self.active = vl.objects.active.name if vl.objects.active else None
        self.preview = {o.name for o in scene.objects if o.get("penumbra_preview") is not None}
        self.images = {i.name for i in bpy.data.images}

    def restore(self):
        for ob in self.scene.objects:
            want = ob.name in self.preview
            has = ob.get("penumbra_preview") is not None
            if want and not has:
                preview_on(ob)
            elif has and not want:
                preview_off(ob)
        for s, v in zip(self.structs, self.values):
            _rna_restore(s, v)
        self.scene.camera = self.camera
        for o in self.vl.objects:
            o.select_set(o.name in self.selected)
        self.vl.objects.active = self.vl.objects.get(self.active) if self.active else None
        # A render makes the "Render Result" image when the file had none; leave the file as it was.
        for img in list(bpy.data.images):
            if img.name not in self.images and img.type == "RENDER_RESULT":
                bpy.data.images.remove(img)


def _path_tracing(scene, samples, bounces, seed):
    c = scene.cycles
    scene.render.engine = "CYCLES"
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_animated_seed = False
    c.seed = seed
    # This Cycles build has no OpenImageDenoise, and a denoised reference would be biased anyway.
    c.use_denoising = False
    for vl in scene.view_layers:
        vl.cycles.use_denoising = False
    # Default diffuse_bounces=4 is 2 % dark in a closed room; clamping biases by several percent (facts §2, §8).
    c.max_bounces = max(c.max_bounces, bounces)
    c.diffuse_bounces = max(c.diffuse_bounces, bounces)
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0


# ---------------------------------------------------------------------------------------------- images

def _read_exr(path):
    """{pass name: (H, W, C) float32, rows top to bottom} from a multilayer EXR."""
    data, names = read_float_image(path, path)
    passes = {}
    for i, n in enumerate(names):
        parts = n.split(".")
        key = parts[-2] if len(parts) >= 2 else "Combined"
        passes.setdefault(key, []).append((parts[-1], i))
    order = "RGBA"
    out = {}
    for key, chans in passes.items():
        chans.sort(key=lambda c: order.index(c[0]) if c[0] in order else 9)
        out[key] = data[..., [i for _, i in chans]]
    return out


def _render(scene, path):
    """Render the scene camera into a multilayer EXR and read back Combined (RGBA) and Emit (RGB)."""
    im = scene.render.image_settings
    compat.multilayer_exr(im)
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    scene.render.use_file_extension = False
    scene.render.filepath = path
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True, scene=scene.name)
    seconds = time.perf_counter() - t
    if not os.path.exists(path):
        raise RuntimeError(f"Cycles wrote no image to {path}")
    p = _read_exr(path)
    return p["Combined"], p.get("Emit"), seconds


def _write_exr(path, rgb_top_down):
    from . import _native
    h, w = rgb_top_down.shape[:2]
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = rgb_top_down[..., :3]
    _native.write_exr(path, np.ascontiguousarray(px[::-1]))


def _srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _write_png(path, rgb_top_down):
    """An 8-bit PNG of display values in [0, 1]; a byte image stores what it is given, with no transform."""
    h, w = rgb_top_down.shape[:2]
    img = bpy.data.images.new("PenumbraComparePNG", w, h, alpha=False)
    try:
        px = np.ones((h, w, 4), np.float32)
        px[..., :3] = np.clip(rgb_top_down[::-1, :, :3], 0.0, 1.0)
        img.pixels.foreach_set(px.ravel())
        img.filepath_raw = path
        img.file_format = "PNG"
        img.save()
    finally:
        bpy.data.images.remove(img)


def false_colour(rel, scale):
    """Diverging map: blue where the bake is darker than the reference, red where brighter, white at 0."""
    t = np.clip(rel / scale, -1.0, 1.0)[..., None]
    white = np.array([1.0, 1.0, 1.0])
    blue = np.array([0.13, 0.30, 0.85])
    red = np.array([0.85, 0.12, 0.10])
    return np.where(t < 0, white + (-t) * (blue - white), white + t * (red - white))


def _tonemap(rgb, white):
    return _srgb(rgb / max(white, 1e-30))


# ---------------------------------------------------------------------------------------------- figures

def error_figures(test, ref, mask, noise=None, floor_fraction=0.01):
    """Relative RMS, mean bias and the 95th-percentile per-sample relative error of `test` against `ref` over
    `mask` (colours as (..., 3)); with `noise` (a sample of the reference's own error) the same figures of the
    noise and the RMS with the noise removed in quadrature."""
    t = test[mask][:, :3].astype(np.float64)
    r = ref[mask][:, :3].astype(np.float64)
    if len(r) == 0 or (r ** 2).sum() <= 0:
        raise ValueError("nothing to compare: no sample is lit in the reference")
    d = t - r
    ref2 = (r ** 2).sum()
    lum_r = r @ LUMA
    # A per-sample relative error needs a floor, or the darkest corners dominate with meaningless ratios.
    floor = floor_fraction * max(lum_r.mean(), 1e-30)
    den = np.maximum(lum_r, floor)
    out = {"samples": int(len(r)),
           "relative_rms": float(math.sqrt((d ** 2).sum() / ref2)),
           "mean_bias": float(d.sum() / r.sum()),
           "p95_relative_error": float(np.percentile(np.abs(d @ LUMA) / den, 95))}
    if noise is not None:
        n = noise[mask][:, :3].astype(np.float64)
        out["noise_relative_rms"] = float(math.sqrt((n ** 2).sum() / ref2))
        out["noise_p95_relative"] = float(np.percentile(np.abs(n @ LUMA) / den, 95))
        out["relative_rms_corrected"] = float(math.sqrt(max(out["relative_rms"] ** 2
                                                            - out["noise_relative_rms"] ** 2, 0.0)))
    return out


# ---------------------------------------------------------------------------------------------- camera space

def _emitter_coverage(scene, path):
    """(H, W, 3) > 0 where a pixel sees an emitting surface, for when the render file has no Emit pass: Blender
    5.x writes only Combined to the multilayer EXR although the pass is enabled (without this mask the lamp's
    pixels, where preview and reference agree by construction, diluted the measured bias: +25 % read as +10 %).
    Every mesh that does not emit becomes a holdout, so alpha is left only where an emitter is seen, occluders
    included."""
    held = [ob for ob in scene.objects if ob.type == "MESH" and not ob.is_holdout and not _material_emits(ob)]
    for ob in held:
        ob.is_holdout = True
    try:
        img, _, _ = _render(scene, path)
    finally:
        for ob in held:
            ob.is_holdout = False
    return np.repeat(img[..., 3:4], 3, axis=-1)


def _camera_compare(scene, samples, out_dir, bounces, seed, preview_samples, heat_scale, progress):
    if scene.camera is None:
        raise ValueError(f"scene '{scene.name}' has no camera to render from")
    baked = [o.name for o in scene.objects if baked_state(o)]
    if not baked:
        raise ValueError("nothing in the scene is baked: run penumbra.bake(scene) first")
    scene.render.film_transparent = True       # alpha marks the background
    for vl in scene.view_layers:
        vl.use_pass_emit = True                  # the Emit pass marks pixels that see an emitter
    half = max(samples // 2, 1)
    tmp = tempfile.mkdtemp(prefix="penumbra_compare_")
    set_preview(scene, False)
    _path_tracing(scene, half, bounces, seed)
    progress("cycles", 0.0)
    a, emit_a, t_a = _render(scene, os.path.join(tmp, "a.exr"))
    progress("cycles", 0.5)
    scene.cycles.seed = seed + 1
    b, emit_b, t_b = _render(scene, os.path.join(tmp, "b.exr"))
    if emit_a is None or emit_b is None:
        emit_a = emit_b = _emitter_coverage(scene, os.path.join(tmp, "e.exr"))
    progress("penumbra", 0.0)
    set_preview(scene, True)
    # The preview only emits, so the samples only anti-alias; the same filter keeps edges comparable.
    _path_tracing(scene, preview_samples, bounces, seed)
    p, _, t_p = _render(scene, os.path.join(tmp, "p.exr"))
    set_preview(scene, False)
    progress("figures", 0.0)

    ref = 0.5 * (a[..., :3] + b[..., :3])
    noise = 0.5 * (a[..., :3] - b[..., :3])
    alpha = np.minimum(a[..., 3], b[..., 3])
    emit = np.maximum(emit_a[..., :3].max(-1), emit_b[..., :3].max(-1))
    mask = (alpha > 0.999) & (emit <= 0.0)
    figs = error_figures(p[..., :3], ref, mask, noise)
    figs.update({"space": "CAMERA", "pixels": int(mask.sum()), "width": int(ref.shape[1]),
                 "height": int(ref.shape[0]), "samples": 2 * half, "preview_samples": preview_samples,
                 "bounces": max(bounces, scene.cycles.diffuse_bounces),
                 "seconds": {"cycles": t_a + t_b, "preview_render": t_p}})
    figs["files"] = _write_outputs(out_dir, "camera", ref, p[..., :3], mask, heat_scale)
    shutil.rmtree(tmp, ignore_errors=True)
    return figs


def _write_outputs(out_dir, stem, ref, test, mask, heat_scale):
    if not out_dir:
        return {}
    out_dir = bpy.path.abspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    files = {"cycles_exr": os.path.join(out_dir, f"{stem}_cycles.exr"),
             "penumbra_exr": os.path.join(out_dir, f"{stem}_penumbra.exr"),
             "heatmap_png": os.path.join(out_dir, f"{stem}_difference.png"),
             "side_by_side_png": os.path.join(out_dir, f"{stem}_side_by_side.png")}
    _write_exr(files["cycles_exr"], ref)
    _write_exr(files["penumbra_exr"], test)
    lum_r = ref @ LUMA
    lum_t = test @ LUMA
    floor = 0.01 * max(lum_r[mask].mean() if mask.any() else 0.0, 1e-30)
    rel = (lum_t - lum_r) / np.maximum(lum_r, floor)
    heat = false_colour(rel, heat_scale)
    heat[~mask] = 0.15
    _write_png(files["heatmap_png"], heat)
    white = float(np.percentile(lum_r[mask], 99)) if mask.any() else float(lum_r.max())
    gap = np.ones((ref.shape[0], max(ref.shape[1] // 50, 2), 3))
    _write_png(files["side_by_side_png"],
               np.concatenate([_tonemap(ref, white), gap, _tonemap(test, white), gap, heat], axis=1))
    return files


# ---------------------------------------------------------------------------------------------- lightmap space

# Blender's bake moves every UV by this many texels before its scan conversion (render/intern/bake.c in 3.4, against
# pixel-aligned UVs): a texel whose centre lies on an island's edge, or within these few thousandths of it, is
# never baked. Sampled at the centre alone, a face narrower than a texel claimed texels that Cycles leaves at 0,
# and the scoring took them for unlit faces (stop 36: four such faces were a quarter of the scaling office's error).
BAKE_SHIFT = (0.001, 0.002)


def uv_owner(mesh, uv_name, width, height):
    """Index of the polygon whose UV footprint holds each texel centre, -1 outside every island; (H, W),
    rows bottom to top like Image.pixels. The centres are moved as Blender's bake moves them (BAKE_SHIFT), so
    a texel is owned exactly where a Cycles bake writes it."""
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers[uv_name].data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2).astype(np.float64)
    mesh.calc_loop_triangles()
    owner = np.full((height, width), -1, np.int64)
    for tri in mesh.loop_triangles:
        a, b, c = (uv[l] for l in tri.loops)
        x0 = max(int(math.floor(min(a[0], b[0], c[0]) * width - 0.5)), 0)
        x1 = min(int(math.ceil(max(a[0], b[0], c[0]) * width - 0.5)), width - 1)
        y0 = max(int(math.floor(min(a[1], b[1], c[1]) * height - 0.5)), 0)
        y1 = min(int(math.ceil(max(a[1], b[1], c[1]) * height - 0.5)), height - 1)
        if x1 < x0 or y1 < y0:
            continue
        px, py = np.meshgrid((np.arange(x0, x1 + 1) + 0.5 + BAKE_SHIFT[0]) / width,
                             (np.arange(y0, y1 + 1) + 0.5 + BAKE_SHIFT[1]) / height)

        def edge(p0, p1):
            return (p1[0] - p0[0]) * (py - p0[1]) - (p1[1] - p0[1]) * (px - p0[0])
        e0, e1, e2 = edge(a, b), edge(b, c), edge(c, a)
        inside = ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
        sub = owner[y0:y1 + 1, x0:x1 + 1]
        sub[inside & (sub < 0)] = tri.polygon_index
    return owner


def face_means(pixels, owner, n_faces):
    """Per-polygon average of the texels it owns; (means (P, 3), counts (P,))."""
    valid = owner >= 0
    o = owner[valid]
    count = np.bincount(o, minlength=n_faces)
    rgb = pixels[..., :3][valid].astype(np.float64)
    means = np.stack([np.bincount(o, weights=rgb[:, c], minlength=n_faces) for c in range(3)], axis=1)
    return means / np.maximum(count, 1)[:, None], count


def _material_emits(ob):
    return any(s.material is not None and parse_material(s.material).emits for s in ob.material_slots)


def cycles_lightmaps(scene, jobs, samples, seed=0, bounces=32, margin=4):
    """Cycles DIFFUSE bakes (Direct + Indirect + Color) of objects into their own UV maps.

    `jobs` maps object name -> (uv map name, width, height). Objects whose materials are not shared are baked
    in one call per UV map name (one scene sync), the others one by one. Returns ({name: (H, W, 4) float32,
    rows bottom to top}, seconds spent in Cycles). The caller restores render settings and selection; the
    image nodes and images made here are removed before returning.
    """
    _path_tracing(scene, samples, bounces, seed)
    vl = bpy.context.view_layer
    uv_of = {name: uv_name for name, (uv_name, w, h) in jobs.items()}
    batches = [{"uv": uv_of[names[0]], "names": names} for names in bake_batches(
        uv_of, lambda n: {s.material.name for s in bpy.data.objects[n].material_slots if s.material is not None})]
    result, seconds = {}, 0.0
    def node_materials(name):
        mats = [slot.material for slot in bpy.data.objects[name].material_slots]
        if any(m is None or not compat.uses_nodes(m) for m in mats):
            raise ValueError(f"{name}: Cycles can bake only objects whose material slots all hold node materials")
        return mats

    for b in batches:
        sizes = {name: jobs[name][1:] for name in b["names"]}
        with bake_targets("PenumbraCompare_", sizes, node_materials) as images:
            for o in vl.objects:
                o.select_set(False)
            for name in b["names"]:
                bpy.data.objects[name].select_set(True)
            vl.objects.active = bpy.data.objects[b["names"][0]]
            t = time.perf_counter()
            r = bpy.ops.object.bake(type="DIFFUSE", pass_filter={"DIRECT", "INDIRECT", "COLOR"}, margin=margin,
                                    margin_type="EXTEND", use_clear=True, target="IMAGE_TEXTURES",
                                    uv_layer=b["uv"])
            seconds += time.perf_counter() - t
            if r != {"FINISHED"}:
                raise RuntimeError(f"Cycles bake of {', '.join(b['names'])} returned {r}")
            for name, img in images.items():
                result[name] = image_rgba(img)
    return result, seconds


def _lightmap_compare(scene, samples, out_dir, bounces, seed, heat_scale, progress):
    jobs, pen = {}, {}
    for ob in scene.objects:
        st = baked_state(ob)
        img = bpy.data.images.get(st.get("image", "")) if st.get("image") else None
        if ob.type != "MESH" or img is None or _material_emits(ob) or not ob.material_slots:
            continue
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        pen[ob.name] = px.reshape(h, w, 4)
        jobs[ob.name] = (st["uv_map"], w, h)
    if not jobs:
        raise ValueError("no baked lightmap to compare: bake with the LIGHTMAP target first (objects that emit "
                         "or have no material are not compared)")
    set_preview(scene, False)   # a Cycles bake of the preview materials would bake their emission
    half = max(samples // 2, 1)
    progress("cycles", 0.0)
    a, t_a = cycles_lightmaps(scene, jobs, half, seed, bounces)
    progress("cycles", 0.5)
    b, t_b = cycles_lightmaps(scene, jobs, half, seed + 1, bounces)
    progress("figures", 0.0)
    per_object, texel, face = {}, [], []
    for name in jobs:
        ob = bpy.data.objects[name]
        uv_name, w, h = jobs[name]
        owner = uv_owner(ob.data, uv_name, w, h)
        ref = 0.5 * (a[name] + b[name])
        noise = 0.5 * (a[name] - b[name])
        mask = owner >= 0
        texel.append((pen[name][mask][:, :3], ref[mask][:, :3], noise[mask][:, :3]))
        n = len(ob.data.polygons)
        fp, cnt = face_means(pen[name], owner, n)
        fr, _ = face_means(ref, owner, n)
        fn, _ = face_means(noise, owner, n)
        keep = cnt > 0
        face.append((fp[keep], fr[keep], fn[keep]))
        if (ref[mask][:, :3] ** 2).sum() > 0:
            per_object[name] = error_figures(pen[name], ref, mask, noise)
        if out_dir:
            flip = (slice(None, None, -1),)
            per_object.setdefault(name, {})["files"] = _write_outputs(
                out_dir, f"lightmap_{bpy.path.clean_name(name)}", ref[flip][..., :3], pen[name][flip][..., :3],
                mask[flip], heat_scale)

    def pooled(parts):
        t, r, n = (np.concatenate([p[i] for p in parts]) for i in range(3))
        m = np.ones(len(r), bool)
        return error_figures(t, r, m, n)
    figs = {"space": "LIGHTMAP", "texels": pooled(texel), "faces": pooled(face), "objects": per_object,
            "samples": 2 * half, "bounces": max(bounces, scene.cycles.diffuse_bounces),
            "seconds": {"cycles": t_a + t_b}}
    for key in ("relative_rms", "mean_bias", "p95_relative_error", "noise_relative_rms", "noise_p95_relative",
                "relative_rms_corrected"):
        figs[key] = figs["texels"][key]
    return figs


# ---------------------------------------------------------------------------------------------- entry point

def compare_cycles(scene=None, samples=256, out_dir=None, space="CAMERA", bounces=32, seed=0,
                   preview_samples=16, heat_scale=0.2, progress=None):
    """Compare the scene's Penumbra bake with Cycles.

    space="CAMERA": render the scene camera with Cycles path tracing (`samples` in two seeded halves) and
    with the bake shown; figures over pixels that see neither an emitter nor the background.
    space="LIGHTMAP": Cycles DIFFUSE bake into each baked object's lightmap UV map; figures per texel
    (top level) and per face (`faces`).
    With `out_dir`, writes <stem>_cycles.exr, <stem>_penumbra.exr, <stem>_difference.png (relative difference of
    luminance, blue = bake darker, red = brighter, full colour at +-heat_scale) and <stem>_side_by_side.png
    (Cycles | Penumbra | difference). Returns a dict of figures; every setting it changed is restored.
    """
    scene = scene or bpy.context.scene
    if space not in {"CAMERA", "LIGHTMAP"}:
        raise ValueError(f"space must be 'CAMERA' or 'LIGHTMAP', got {space!r}")
    if not isinstance(samples, int) or samples < 2:
        raise ValueError(f"samples must be an integer >= 2 (two seeded halves), got {samples!r}")
    if bpy.context.scene != scene:
        raise ValueError("compare_cycles works on the context's scene (Cycles bakes and renders need it)")

    def step(stage, frac):
        if progress is not None:
            progress(stage, frac)
    if bpy.context.object is not None and bpy.context.object.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    state = _SceneState(scene)
    t = time.perf_counter()
    try:
        if space == "CAMERA":
            figs = _camera_compare(scene, samples, out_dir, bounces, seed, preview_samples, heat_scale, step)
        else:
            figs = _lightmap_compare(scene, samples, out_dir, bounces, seed, heat_scale, step)
    finally:
        state.restore()
    figs["seconds"]["total"] = time.perf_counter() - t
    step("done", 1.0)
    return figs


def summary(figs):
    s = (f"Penumbra vs Cycles ({figs['space'].lower()}, {figs['samples']} spp): relative RMS "
         f"{100 * figs['relative_rms']:.2f} % (reference noise {100 * figs['noise_relative_rms']:.2f} %, "
         f"without it {100 * figs['relative_rms_corrected']:.2f} %), mean bias {100 * figs['mean_bias']:+.2f} %, "
         f"95th percentile {100 * figs['p95_relative_error']:.1f} % (noise {100 * figs['noise_p95_relative']:.1f} %)")
    if figs["space"] == "LIGHTMAP":
        f = figs["faces"]
        s += (f"; per-face averages: relative RMS {100 * f['relative_rms']:.2f} % (noise "
              f"{100 * f['noise_relative_rms']:.2f} %), bias {100 * f['mean_bias']:+.2f} %")
    return s


# ---------------------------------------------------------------------------------------------- operator

class PENUMBRA_OT_compare_cycles(bpy.types.Operator):
    bl_idname = "penumbra.compare_cycles"
    bl_label = "Compare with Cycles"
    bl_description = ("Render the camera (or bake the lightmaps) with Cycles path tracing and report the error "
                      "of the Penumbra bake against it; writes EXRs and difference images when a folder is set")
    bl_options = {"REGISTER"}

    samples: bpy.props.IntProperty(name="Samples", default=256, min=2, max=1 << 20)
    space: bpy.props.EnumProperty(name="Space", items=(("CAMERA", "Camera", "Render the scene camera"),
                                                       ("LIGHTMAP", "Lightmap", "Cycles DIFFUSE bake per texel")),
                                  default="CAMERA")
    out_dir: bpy.props.StringProperty(name="Output", default="", subtype="DIR_PATH")

    def execute(self, context):
        try:
            figs = compare_cycles(context.scene, samples=self.samples, out_dir=self.out_dir or None,
                                  space=self.space)
        except Exception as e:
            self.report({"ERROR"}, f"Penumbra: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, summary(figs))
        return {"FINISHED"}


def register():
    bpy.utils.register_class(PENUMBRA_OT_compare_cycles)


def unregister():
    bpy.utils.unregister_class(PENUMBRA_OT_compare_cycles)
