"""The operator `penumbra.bake` and a small panel in Properties > Render: thin shells over `penumbra.bake()`."""
import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, PointerProperty, StringProperty


class PenumbraSettings(bpy.types.PropertyGroup):
    resolution: IntProperty(name="Resolution", description="Lightmap width and height in texels",
                            default=256, min=8, max=16384)
    margin: IntProperty(name="Margin", description="Texels filled past the UV islands", default=4, min=0,
                        max=64)
    epsilon: FloatProperty(name="Quality", description="Refinement threshold, relative to the brightest "
                           "emitter (smaller is finer and slower)", default=0.0002, min=1e-6, max=1.0,
                           precision=4)
    lightmap: BoolProperty(name="Lightmaps", default=True)
    color_attribute: BoolProperty(name="Color Attributes", default=True)
    uv_map: StringProperty(name="UV Map", description="Existing UV map for the lightmaps; empty = create "
                           "and unwrap 'PenumbraLightmap'", default="")
    selection_only: BoolProperty(name="Selected Only", default=False)
    output_dir: StringProperty(name="Output", description="Also write the lightmaps as EXR files here",
                               default="", subtype="DIR_PATH")

    def as_settings(self):
        targets = {t for t, on in (("LIGHTMAP", self.lightmap), ("COLOR_ATTRIBUTE", self.color_attribute)) if on}
        return {"resolution": self.resolution, "margin": self.margin, "epsilon": self.epsilon,
                "targets": targets, "uv_map": self.uv_map or None, "selection_only": self.selection_only,
                "output_dir": self.output_dir or None}


class PENUMBRA_OT_bake(bpy.types.Operator):
    bl_idname = "penumbra.bake"
    bl_label = "Bake Radiosity"
    bl_description = "Solve diffuse global illumination and bake it into lightmaps and color attributes"
    bl_options = {"REGISTER"}

    def execute(self, context):
        import penumbra
        try:
            report = penumbra.bake(context.scene, **context.scene.penumbra.as_settings())
        except Exception as e:  # the bake left the .blend untouched; say why it stopped
            cancelled = penumbra.Cancelled is not None and isinstance(e, penumbra.Cancelled)
            self.report({"WARNING" if cancelled else "ERROR"}, f"Penumbra: {e}")
            return {"CANCELLED"}
        for w in report["warnings"]:
            self.report({"WARNING"}, w)
        for x in report["skipped"]:
            self.report({"WARNING"}, f"skipped {x['name']}: {x['reason']}")
        self.report({"INFO"}, penumbra.summary(report))
        return {"FINISHED"}

    def invoke(self, context, event):
        # The modal, threaded bake with a progress bar is a later step; headless there is no event loop anyway.
        return self.execute(context)


class PENUMBRA_OT_preview(bpy.types.Operator):
    bl_idname = "penumbra.preview"
    bl_label = "Preview Bake"
    bl_description = "Show (or stop showing) the baked light in the viewport and in renders"
    bl_options = {"REGISTER", "UNDO"}
    on: BoolProperty(default=True)

    def execute(self, context):
        import penumbra
        penumbra.preview(context.scene, self.on)
        return {"FINISHED"}


class PENUMBRA_OT_clear(bpy.types.Operator):
    bl_idname = "penumbra.clear"
    bl_label = "Clear Bake"
    bl_description = "Remove the lightmaps, color attributes and UV maps that Penumbra made"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        import penumbra
        penumbra.clear(context.scene)
        return {"FINISHED"}


class PENUMBRA_PT_render(bpy.types.Panel):
    bl_label = "Penumbra"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        s = context.scene.penumbra
        col = self.layout.column()
        col.prop(s, "resolution")
        col.prop(s, "epsilon")
        col.prop(s, "margin")
        row = col.row()
        row.prop(s, "lightmap")
        row.prop(s, "color_attribute")
        col.prop(s, "uv_map")
        col.prop(s, "selection_only")
        col.prop(s, "output_dir")
        col.operator("penumbra.bake", icon="RENDER_STILL")
        row = col.row()
        row.operator("penumbra.preview", text="Preview On").on = True
        row.operator("penumbra.preview", text="Preview Off").on = False
        col.operator("penumbra.clear")


CLASSES = (PenumbraSettings, PENUMBRA_OT_bake, PENUMBRA_OT_preview, PENUMBRA_OT_clear, PENUMBRA_PT_render)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.penumbra = PointerProperty(type=PenumbraSettings)


def unregister():
    del bpy.types.Scene.penumbra
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
