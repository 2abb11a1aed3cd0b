"""A world that is more than a uniform colour or a plain equirectangular image (a Sky Texture, gradients, mixes,
mapped or mirror-ball images, any node tree): Cycles itself evaluates it, by rendering the world alone through
an equirectangular panoramic camera into a float image, which then lights the scene as an environment map
(the solver's WORLD light with an `environment`). Nothing here models a sky: whatever Cycles shows a camera
ray is what the bake receives.

What a camera ray sees is what a diffuse ray sees unless the world's node tree asks the Light Path node which
ray it is, or the world's ray visibility differs between camera and diffuse rays; both are told apart in the
docs (addon.md), not here. The render is made in a scene of its own (only the world is shared), so the
user's scene, its settings and its Render Result are left as they were.
"""
import os
import tempfile

import bpy
import numpy as np

from . import compat

# 512 x 256 puts a pixel at 0.7 degrees: a clear sky's irradiance varies over tens of degrees. A Sky Texture's
# sun disc (half a degree, most of the light) is taken out of the map and sent as a SUN lamp instead
# (render_world_and_sun).
WIDTH, HEIGHT = 512, 256
SAMPLES = 16
# Cycles' equirectangular camera looks along its local -Z; turned so, its image uses the Environment
# Texture's own mapping (u = 0.5 - atan2(y, x) / 2 pi, v = 0.5 + elevation / pi): checked by rendering a world
# whose colour is its direction, 0.3 % mean error (the pixel filter's) at 64 x 32.
CAMERA_ROTATION = (np.pi / 2, 0.0, -np.pi / 2)
SUN_SCALE, SUN_WINDOW, SUN_SAMPLES, SUN_FIND = 8, 2.0, 64, 8.0


def render_world(world, width=WIDTH, height=HEIGHT, samples=SAMPLES, turn=0.0, window=None):
    """The world's radiance in every direction as (height, width, 3) float32, linear, rows from the bottom
    (straight down) up, in the Environment Texture's equirectangular mapping. Raises RuntimeError when Cycles
    renders nothing. `turn` (radians) turns the camera about +Z, and every pixel's direction with it;
    `window` (x0, x1, y0, y1), in pixels from the bottom left, renders and returns only those pixels."""
    made_scene = bpy.data.scenes.new("PenumbraWorldMap")
    cam_data = bpy.data.cameras.new("PenumbraWorldMap")
    cam = None
    images_before = {img.name for img in bpy.data.images}
    fd, path = tempfile.mkstemp(prefix="penumbra_world_", suffix=".exr")
    os.close(fd)
    try:
        sc = made_scene
        sc.world = world
        sc.render.engine = "CYCLES"
        c = sc.cycles
        c.device = "CPU"
        c.samples = samples
        c.use_adaptive_sampling = False
        c.use_denoising = False            # Debian's Cycles has no OpenImageDenoise
        for vl in sc.view_layers:
            vl.cycles.use_denoising = False
        sc.render.resolution_x, sc.render.resolution_y = width, height
        sc.render.resolution_percentage = 100
        sc.render.film_transparent = False
        sc.view_settings.view_transform = "Standard"
        sc.view_settings.look = "None"
        sc.view_settings.exposure = 0.0
        sc.view_settings.gamma = 1.0
        cam_data.type = "PANO"
        compat.panorama_settings(cam_data).panorama_type = "EQUIRECTANGULAR"
        cam = bpy.data.objects.new("PenumbraWorldMap", cam_data)
        cam.rotation_euler = (CAMERA_ROTATION[0], CAMERA_ROTATION[1], CAMERA_ROTATION[2] + turn)
        if window is not None:
            # Whole pixels (k / width is exact in binary), so the cropped image is exactly the window.
            r = sc.render
            r.use_border, r.use_crop_to_border = True, True
            r.border_min_x, r.border_max_x = window[0] / width, window[1] / width
            r.border_min_y, r.border_max_y = window[2] / height, window[3] / height
        sc.collection.objects.link(cam)
        sc.camera = cam
        im = sc.render.image_settings
        compat.single_layer_exr(im)
        im.color_depth = "32"
        im.color_mode = "RGB"
        sc.render.use_file_extension = False
        sc.render.filepath = path
        with _camera_sees_world(world):
            bpy.ops.render.render(write_still=True, scene=sc.name)
        rgb = _read_rgb(path)
    finally:
        if cam is not None:
            bpy.data.objects.remove(cam)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(made_scene)
        for img in list(bpy.data.images):
            if img.name not in images_before and img.type == "RENDER_RESULT":
                bpy.data.images.remove(img)
        try:
            os.remove(path)
        except OSError:
            pass
    shape = (height, width, 3) if window is None else (window[3] - window[2], window[1] - window[0], 3)
    if rgb.shape != shape or not np.isfinite(rgb).all():
        raise RuntimeError("Cycles' render of the world gave no usable image")
    return np.ascontiguousarray(np.maximum(rgb, 0.0), np.float32)


class _camera_sees_world:
    """A world hidden from camera rays (Ray Visibility > Camera off) still lights the scene: show it to the
    panoramic camera for the render, then put the flag back."""

    def __init__(self, world):
        self.vis = compat.world_ray_visibility(world)
        self.old = None

    def __enter__(self):
        if self.vis is not None and not self.vis.camera:
            self.old = False
            self.vis.camera = True
        return self

    def __exit__(self, *exc):
        if self.old is not None:
            self.vis.camera = self.old
        return False


def read_float_image(path, what):
    """(pixels (H, W, C) float32 with rows top to bottom, channel names) of an EXR Cycles wrote; `what` names it
    in the error."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"cannot read {what} ({oiio.geterror()})")
    try:
        spec = inp.spec()
        px = np.asarray(inp.read_image(oiio.FLOAT)).reshape(spec.height, spec.width, spec.nchannels)
        return px, list(spec.channelnames)
    finally:
        inp.close()


def _read_rgb(path):
    px, _ = read_float_image(path, "the world image Cycles wrote")
    return px[::-1, :, :3].astype(np.float32)      # EXR rows run top down


def sky_sun_discs(world):
    """Sky Texture nodes of a world's tree whose sun disc is on: a disc of about half a degree that carries most
    of the light, which a map sampled along fixed directions cannot resolve."""
    if world is None or not compat.uses_nodes(world):
        return []
    return [n for n in world.node_tree.nodes if n.type == "TEX_SKY" and getattr(n, "sun_disc", False)]


def pixel_directions(width, height, window=None):
    """Unit direction of every pixel centre of the equirectangular map, (rows, columns, 3), rows from the
    bottom, and each pixel's solid angle (rows, 1); of the pixels of `window` (x0, x1, y0, y1) only."""
    x0, x1, y0, y1 = window if window is not None else (0, width, 0, height)
    u = (np.arange(x0, x1) + 0.5) / width
    v = (np.arange(y0, y1) + 0.5) / height
    phi, el = np.meshgrid((0.5 - u) * 2 * np.pi, (v - 0.5) * np.pi)
    d = np.stack([np.cos(el) * np.cos(phi), np.cos(el) * np.sin(phi), np.sin(el)], axis=-1)
    solid = (2 * np.pi / width) * (np.pi / height) * np.cos(el[:, :1])
    return d, solid


def render_world_and_sun(world, width=WIDTH, height=HEIGHT, samples=SAMPLES):
    """(map, suns): the world's map without its Sky Textures' sun discs, and each disc as a SUN light dict
    (the difference of two renders, with and without the discs, integrated over the sphere: its irradiance at
    normal incidence and its mean direction; the disc's angular size from the node). The map alone would
    spread the disc's light over a pixel and reach it along a few of its fixed directions or none."""
    discs = sky_sun_discs(world)
    if not discs:
        return render_world(world, width, height, samples), []
    # Where the disc is: a quarter-resolution pass with each disc blown up to SUN_FIND degrees (its centre
    # stays; at its own half degree, a few samples per 2.8 degree pixel missed it). Then the disc alone,
    # precisely: a window of +-SUN_WINDOW degrees about that centre, rendered SUN_SCALE times finer with
    # SUN_SAMPLES samples, with the camera turned so the window cannot wrap around the map's seam. From the
    # 16-sample map itself the disc's irradiance came out 13 % high at one sample count and 1 % low at another.
    sizes = [n.sun_size for n in discs]
    try:
        for n in discs:
            n.sun_disc = False
        sky = render_world(world, width, height, samples)
        for n in discs:
            n.sun_disc = True
            n.sun_size = max(n.sun_size, np.radians(SUN_FIND))
        coarse_on = render_world(world, width // 4, height // 4, 4)
    finally:
        for n, size in zip(discs, sizes):
            n.sun_disc = True
            n.sun_size = size
    h4, w4 = height // 4, width // 4
    coarse_off = sky[:h4 * 4, :w4 * 4].reshape(h4, 4, w4, 4, 3).mean(axis=(1, 3))
    weight = np.maximum(coarse_on - coarse_off, 0.0).sum(axis=2) * pixel_directions(w4, h4)[1]
    if not weight.max() > 0:
        return render_world(world, width, height, samples), []   # the disc is below the horizon: keep it all
    weight[weight < 0.1 * weight.max()] = 0       # the two passes' noise elsewhere would pull the centre
    dirs, _ = pixel_directions(w4, h4)
    peak = (dirs * weight[..., None]).sum(axis=(0, 1))
    peak /= np.linalg.norm(peak)
    azimuth = float(np.arctan2(peak[1], peak[0]))
    elevation = float(np.arcsin(np.clip(peak[2], -1, 1)))
    W, H = width * SUN_SCALE, height * SUN_SCALE
    half_y = int(np.ceil(SUN_WINDOW / 180.0 * H))
    half_x = min(W // 2 - 1, int(np.ceil(SUN_WINDOW / 360.0 * W / max(np.cos(elevation), 0.02))))
    yc = int((0.5 + elevation / np.pi) * H)
    window = (W // 2 - half_x, W // 2 + half_x, max(0, yc - half_y), min(H, yc + half_y))
    # Column W / 2 looks along +X; turned by the peak's azimuth it looks at the peak.
    turn = azimuth
    on = render_world(world, W, H, SUN_SAMPLES, turn, window)
    try:
        for n in discs:
            n.sun_disc = False
        off = render_world(world, W, H, SUN_SAMPLES, turn, window)
    finally:
        for n in discs:
            n.sun_disc = True
    diff = np.maximum(on - off, 0.0).astype(np.float64)
    fine, solid = pixel_directions(W, H, window)
    c, s_ = np.cos(turn), np.sin(turn)
    fine = np.stack([c * fine[..., 0] - s_ * fine[..., 1], s_ * fine[..., 0] + c * fine[..., 1], fine[..., 2]], -1)
    w = diff.sum(axis=2) * solid
    mean = (fine * w[..., None]).sum(axis=(0, 1))
    mean /= np.linalg.norm(mean)
    irradiance = (diff * solid[..., None]).sum(axis=(0, 1))       # W/m^2 at normal incidence, per channel
    angle = float(max(n.sun_size for n in discs))
    # A SUN of strength S and angular diameter a gives S * f(a) at normal incidence (blender-facts section 1).
    t = np.tan(0.5 * angle)
    f = 2 * (np.sqrt(1 + t * t) - 1) / (t * t) if t > 1e-4 else 1.0
    sun = {"type": "SUN", "value": tuple(float(x) for x in irradiance / f), "direction": tuple(float(x) for x in -mean),
           "angle": angle, "cast_shadow": True}
    return sky, [sun]
