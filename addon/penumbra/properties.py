"""Settings saved with the .blend (scene.penumbra, object.penumbra_settings) and the running bake's state
(window_manager.penumbra, not saved).

The object-level group is not called `object.penumbra`: registered properties live in the ID's custom
properties under their own name, and `ob["penumbra"]` already holds what the last bake made (writeback.PROP).
"""
import json

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from . import MAX_RESOLUTION

# Solver thresholds per quality preset. Measured on the Cornell box (examples/cornell_box.py, 128x128
# lightmaps) against the Cycles reference in blender_tests/data, 2 shared cores; see docs/ui.md.
PRESETS = {
    "DRAFT": {"epsilon": 0.002, "min_size": 0.02},
    "MEDIUM": {"epsilon": 0.0005, "min_size": 0.01},
    "HIGH": {"epsilon": 0.0002, "min_size": 0.005},
}
QUALITY_ITEMS = (
    ("DRAFT", "Draft", "Fast look at the lighting: Cornell box about 0.2 s, 4.7 % from a converged path "
     "tracer (epsilon 0.002, smallest patch 0.02)"),
    ("MEDIUM", "Medium", "Cornell box about 0.3 s, 2.6 % from a converged path tracer (epsilon 0.0005, "
     "smallest patch 0.01)"),
    ("HIGH", "High", "Cornell box about 0.7 s, 1.8 % from a converged path tracer; shadows and corners get "
     "the finest patches (epsilon 0.0002, smallest patch 0.005)"),
    ("CUSTOM", "Custom", "The thresholds set under Advanced"),
)


_applying = False      # a preset is writing the thresholds: do not switch the preset to Custom


def _apply_preset(self, context):
    global _applying
    values = PRESETS.get(self.quality)
    if values is None:
        return
    _applying = True
    try:
        self.epsilon = values["epsilon"]
        self.min_size = values["min_size"]
    finally:
        _applying = False


def _threshold_edited(self, context):
    if _applying:
        return
    match = next((k for k, v in PRESETS.items()
                  if abs(v["epsilon"] - self.epsilon) <= 1e-9 and abs(v["min_size"] - self.min_size) <= 1e-9),
                 "CUSTOM")
    if self.quality != match:
        # Writing the ID property directly does not call _apply_preset back.
        self["quality"] = [i[0] for i in QUALITY_ITEMS].index(match)


class PenumbraSettings(bpy.types.PropertyGroup):
    """scene.penumbra: what the Bake button, the operator and the panel use."""
    selection_only: BoolProperty(
        name="Selected Only",
        description="Bake only the selected objects. The others are left out completely: they neither get a "
                    "lightmap nor cast shadows or bounce light", default=False)
    lightmap: BoolProperty(
        name="Lightmap",
        description="Bake into a 32-bit float image per object (Penumbra_<object>, packed into the .blend), "
                    "mapped with the lightmap UV map", default=True)
    color_attribute: BoolProperty(
        name="Color Attribute",
        description="Bake into a float color attribute 'Penumbra' on the face corners: no UVs needed, detail "
                    "limited to the mesh's vertices", default=True)
    resolution: IntProperty(
        name="Resolution",
        description="Width and height of each object's lightmap, in pixels. Double it for sharper shadows; "
                    "memory and bake time grow with its square (at most 8192: about 4 GB while baking)",
        default=256, min=8, max=MAX_RESOLUTION, soft_max=4096)
    margin: IntProperty(
        name="Margin",
        description="Pixels filled around each UV island so that filtering and mipmaps do not pull in black "
                    "from outside the island", default=4, min=0, max=64)
    uv_map: StringProperty(
        name="UV Map",
        description="Existing UV map to bake the lightmaps into. Empty: Penumbra creates 'PenumbraLightmap' "
                    "and unwraps it (Smart UV Project), leaving your UV maps alone", default="")
    output_dir: StringProperty(
        name="Export EXR",
        description="Also save every lightmap as a 32-bit float EXR file in this folder (optional)",
        default="", subtype="DIR_PATH")
    quality: EnumProperty(
        name="Quality", items=QUALITY_ITEMS, default="HIGH", update=_apply_preset,
        description="How finely the surfaces are subdivided where the light changes. Higher is closer to a "
                    "path-traced reference and slower")
    epsilon: FloatProperty(
        name="Refinement Threshold",
        description="Subdivide wherever the light transfer's error is above this fraction of the brightest "
                    "light. Smaller gives softer, more exact shadows and costs more time and memory",
        default=PRESETS["HIGH"]["epsilon"], min=1e-7, max=1.0, precision=5, step=0.01,
        update=_threshold_edited)
    min_size: FloatProperty(
        name="Smallest Patch",
        description="Surfaces are never cut finer than this fraction of the scene's size (its bounding-box "
                    "diagonal). Smaller resolves sharper shadow edges and costs more memory",
        default=PRESETS["HIGH"]["min_size"], min=1e-5, max=1.0, precision=4, step=0.01,
        update=_threshold_edited)
    visibility_rays: IntProperty(
        name="Shadow Rays",
        description="Rays that test how much of a light or surface another surface sees, where it is partly "
                    "hidden. More rays give smoother penumbras", default=16, min=1, max=256)
    max_iterations: IntProperty(
        name="Max Iterations",
        description="Upper limit on the light-bounce iterations. The report warns when the limit stopped the "
                    "solve before it converged", default=5000, min=1, max=100000)
    tolerance: FloatProperty(
        name="Convergence",
        description="The bounces stop when the estimated remaining error of the light falls below this fraction",
        default=1e-4, min=1e-9, max=0.5, precision=6, step=0.001)
    refine_passes: IntProperty(
        name="Refine Passes",
        description="Times the subdivision is revisited once the bounced light is known: later passes refine "
                    "where indirect light matters", default=3, min=1, max=16)
    threads: IntProperty(
        name="Threads", description="CPU threads for the solver. 0: all cores, except that the Bake button leaves "
                  "one core to Blender so that the window stays responsive", default=0, min=0, max=1024)
    clustering: BoolProperty(
        name="Clustering",
        description="Group faces into clusters so that distant groups exchange light as one. Much faster on "
                    "scenes with many faces; off compares every face with every other face first",
        default=True)
    convolution: BoolProperty(
        name="Shadow Textures",
        description="Let large flat surfaces lit by a flat light through objects take their shadow as one "
                    "texture computed by convolution (Soler & Sillion) instead of a mesh cut finely along the "
                    "penumbra. Used only where the texture meets the error and time limits below",
        default=True)
    a_min: FloatProperty(
        name="Min Receiver Size",
        description="Smallest surface (its bounding-box diagonal, as a fraction of the scene's) that may take a "
                    "shadow texture. Smaller lets more surfaces take one, at more textures",
        default=0.15, min=0.0, max=1.0, precision=3, step=1)
    e_max: FloatProperty(
        name="Max Blocker Error",
        description="How far a shadow texture may misplace a penumbra because its blockers are thick, in units "
                    "of half the narrowest penumbra. Larger accepts more textures and less exact shadows",
        default=1.0, min=0.01, max=100.0, precision=2, step=10)
    t_max: FloatProperty(
        name="Max Texture Time",
        description="Longest predicted time for one shadow texture's FFTs, in seconds; a texture predicted to "
                    "take longer is left to the ordinary refinement", default=0.05, min=1e-4, max=60.0,
        precision=3, step=1, subtype="TIME_ABSOLUTE", unit="TIME_ABSOLUTE")
    max_texture: IntProperty(
        name="Max Texture Size",
        description="Largest shadow texture, in texels per side", default=512, min=16, max=4096)
    last_report: StringProperty(
        name="Last Report", description="The last successful bake's report (JSON), saved with the file",
        default="", options={"HIDDEN"})

    def as_settings(self):
        """The keyword arguments of penumbra.bake() that these settings stand for."""
        targets = {t for t, on in (("LIGHTMAP", self.lightmap), ("COLOR_ATTRIBUTE", self.color_attribute)) if on}
        return {"resolution": self.resolution, "margin": self.margin, "targets": targets,
                "uv_map": self.uv_map or None, "selection_only": self.selection_only,
                "output_dir": self.output_dir or None, "epsilon": self.epsilon, "min_size": self.min_size,
                "visibility_rays": self.visibility_rays, "max_iterations": self.max_iterations,
                "tolerance": self.tolerance, "refine_passes": self.refine_passes, "threads": self.threads,
                "clustering": self.clustering, "convolution": self.convolution, "a_min": self.a_min,
                "e_max": self.e_max, "t_max": self.t_max, "max_texture": self.max_texture}

    def report(self):
        try:
            return json.loads(self.last_report) if self.last_report else None
        except ValueError:
            return None


class PenumbraObjectSettings(bpy.types.PropertyGroup):
    """object.penumbra_settings: per-object opt-out."""
    bake: BoolProperty(
        name="Bake",
        description="Give this object a lightmap and color attribute. When off it still casts shadows and "
                    "bounces light onto the others, but keeps no baked light of its own", default=True)


class PenumbraRuntime(bpy.types.PropertyGroup):
    """window_manager.penumbra: the bake in progress and the last outcome of this session (not saved)."""
    running: BoolProperty(default=False)
    progress: FloatProperty(name="Progress", subtype="PERCENTAGE", min=0, max=100, default=0, precision=0)
    stage: StringProperty(default="")
    scene: StringProperty(default="")
    # "", "FINISHED", "CANCELLED", "ERROR"
    outcome: StringProperty(default="")
    message: StringProperty(default="")
    report: StringProperty(default="")


CLASSES = (PenumbraSettings, PenumbraObjectSettings, PenumbraRuntime)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.penumbra = PointerProperty(type=PenumbraSettings)
    bpy.types.Object.penumbra_settings = PointerProperty(type=PenumbraObjectSettings)
    bpy.types.WindowManager.penumbra = PointerProperty(type=PenumbraRuntime)


def unregister():
    del bpy.types.WindowManager.penumbra
    del bpy.types.Object.penumbra_settings
    del bpy.types.Scene.penumbra
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
