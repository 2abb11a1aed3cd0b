"""Settings saved with the .blend (scene.penumbra, object.penumbra_settings) and the running bake's state
(window_manager.penumbra, not saved).

The object-level group is not called `object.penumbra`: registered properties live in the ID's custom
properties under their own name, and `ob["penumbra"]` already holds what the last bake made (writeback.PROP).
"""
import json

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from . import MAX_RESOLUTION, settings_table

# Solver thresholds per quality preset (settings_table.py; measured on the Cornell box, examples/cornell_box.py,
# 128x128 lightmaps, against the Cycles reference in blender_tests/data, 2 shared cores; see docs/ui.md).
PRESETS = settings_table.PRESETS
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
        for key, value in values.items():
            setattr(self, key, value)
    finally:
        _applying = False


def _threshold_edited(self, context):
    if _applying:
        return
    match = next((k for k, v in PRESETS.items()
                  if all(abs(value - getattr(self, key)) <= 1e-9 for key, value in v.items())), "CUSTOM")
    if self.quality != match:
        # Writing the ID property directly does not call _apply_preset back.
        self["quality"] = [i[0] for i in QUALITY_ITEMS].index(match)


def _solver_property(s):
    """The bpy property of one settings_table entry: its label, help, default and the panel's limits."""
    options = {k: v for k, v in s.blender.items() if k not in ("min", "max")}
    if any(s.name in values for values in PRESETS.values()):
        options["update"] = _threshold_edited      # editing a preset's threshold leaves the preset
    common = dict(name=s.label, description=s.help, default=settings_table.panel_default(s), **options)
    if s.type is bool:
        return BoolProperty(**common)
    lo, hi = settings_table.panel_limits(s)
    return (FloatProperty if s.type is float else IntProperty)(min=lo, max=hi, **common)


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
    patch_texels: FloatProperty(
        name="Smallest Patch (texels)",
        description="Cut surfaces that get a lightmap no finer than this many of its texels, instead of the "
                    "Smallest Patch fraction of the scene: for halls and large planes whose lightmaps show more "
                    "than 1 % of the scene's size. 0: off", default=0.0, min=0.0, max=64.0, soft_max=8.0)
    irradiance: BoolProperty(
        name="Irradiance Only",
        description="Bake the light arriving at each surface (Cycles' Diffuse Direct + Indirect without Color) "
                    "instead of the light it reflects: what a game engine multiplies by its own albedo texture. "
                    "The preview multiplies it by the material's colour", default=False)
    instance_lightmaps: BoolProperty(
        name="Instance Lightmaps",
        description="Give every collection instance of an object a tile of its own in the object's lightmap "
                    "(the preview picks the tile per instance). Off: instances take part in the solve but get "
                    "no baked light", default=False)
    uv_map: StringProperty(
        name="UV Map",
        description="Existing UV map to bake the lightmaps into. Empty: Penumbra creates 'PenumbraLightmap' "
                    "and unwraps it (Smart UV Project), leaving your UV maps alone", default="")
    output_dir: StringProperty(
        name="Export EXR",
        description="Also save every lightmap as a 32-bit float EXR file in this folder (optional)",
        default="", subtype="DIR_PATH")
    quality: EnumProperty(
        name="Quality", items=QUALITY_ITEMS, default=settings_table.DEFAULT_QUALITY, update=_apply_preset,
        description="How finely the surfaces are subdivided where the light changes. Higher is closer to a "
                    "path-traced reference and slower")
    last_report: StringProperty(
        name="Last Report", description="The last successful bake's report (JSON), saved with the file",
        default="", options={"HIDDEN"})

    def as_settings(self):
        """The keyword arguments of penumbra.bake() that these settings stand for."""
        targets = {t for t, on in (("LIGHTMAP", self.lightmap), ("COLOR_ATTRIBUTE", self.color_attribute)) if on}
        s = {"resolution": self.resolution, "margin": self.margin, "targets": targets,
             "uv_map": self.uv_map or None, "selection_only": self.selection_only,
             "output_dir": self.output_dir or None, "irradiance": self.irradiance,
                "instance_lightmaps": self.instance_lightmaps, "patch_texels": self.patch_texels}
        s.update((key, getattr(self, key)) for key in settings_table.SOLVER_KEYS)
        return s

    def report(self):
        try:
            return json.loads(self.last_report) if self.last_report else None
        except ValueError:
            return None


# The solver's settings (the Advanced panel), one property per panel entry of settings_table.SETTINGS; Blender
# reads the annotations when the class is registered.
for _s in settings_table.PANEL:
    PenumbraSettings.__annotations__[_s.name] = _solver_property(_s)
del _s


class PenumbraObjectSettings(bpy.types.PropertyGroup):
    """object.penumbra_settings: per-object opt-out."""
    bake: BoolProperty(
        name="Bake",
        description="Give this object a lightmap and color attribute. When off it still casts shadows and "
                    "bounces light onto the others, but keeps no baked light of its own", default=True)
    two_sided: BoolProperty(
        name="Two-sided",
        description="Light both sides of every face, as Cycles renders them: for open surfaces (planes, "
                    "cards, walls of one face) and flipped normals. Each face then receives and reflects "
                    "light on its back too, and its lightmap holds the brighter of its two sides. Off: the "
                    "side its normal points to only (half the faces to solve)", default=False)


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
