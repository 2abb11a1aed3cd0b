"""The Penumbra panels: Properties > Render, the 3D view sidebar (tab "Penumbra") and Properties > Object."""
import json
import textwrap

import bpy

from . import operators, settings_table
from .writeback import baked_state

MAX_LINES = 8          # skipped objects and warnings listed in the panel; the rest are in the report


def _wrap(layout, text, icon="NONE", width=None):
    """Labels do not wrap; split long messages so object and material names stay readable."""
    width = width or 50
    lines = textwrap.wrap(text, width) or [""]
    col = layout.column(align=True)
    col.scale_y = 0.8
    for i, line in enumerate(lines):
        col.label(text=line, icon=icon if i == 0 else "BLANK1")


def _chars(context):
    region = context.region
    # About 7 px per character of the UI font at 1x scale, less the panel's margins.
    scale = context.preferences.system.ui_scale if context.preferences else 1.0
    return max(24, int((region.width if region else 400) / (7.0 * scale)) - 6)


def _last(context):
    """(outcome, message, report) to show for this scene: this session's last bake, else the saved report."""
    scene = context.scene
    rt = context.window_manager.penumbra
    if rt.scene == scene.name and rt.outcome:
        report = json.loads(rt.report) if rt.report else None
        return rt.outcome, rt.message, report
    report = scene.penumbra.report()
    if report:
        return "FINISHED", "", report
    return "", "", None


class _Render:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"


class _Sidebar:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Penumbra"


class _Main:
    bl_label = "Penumbra"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.penumbra
        rt = context.window_manager.penumbra
        col = layout.column()

        if operators.running_bake() is not None and rt.running:
            box = col.box()
            box.prop(rt, "progress", text=rt.stage, slider=True)
            box.label(text="Esc cancels; the scene stays as it was", icon="INFO")
        else:
            row = col.row()
            row.scale_y = 1.5
            row.operator("penumbra.bake", text="Bake", icon="RENDER_STILL")
            if operators.stopping_workers():
                col.label(text="The cancelled bake is still stopping", icon="TIME")
        row = col.row(align=True)
        shown = operators.scene_preview_on(context.scene)
        row.operator("penumbra.preview", text="Show Bake", icon="HIDE_OFF" if shown else "HIDE_ON",
                     depress=shown)
        row.operator("penumbra.clear", text="Clear", icon="TRASH")

        col.separator()
        col.prop(s, "selection_only", text="Selected Only")
        row = col.row(heading="Bake Into", align=True)
        row.prop(s, "lightmap", toggle=True)
        row.prop(s, "color_attribute", toggle=True)
        if not (s.lightmap or s.color_attribute):
            col.label(text="Choose Lightmap, Color Attribute or both", icon="ERROR")
        sub = col.column(align=True)
        sub.active = s.lightmap
        sub.prop(s, "resolution")
        sub.prop(s, "margin")
        sub.prop(s, "patch_texels")
        ob = context.active_object
        if ob is not None and ob.type == "MESH":
            sub.prop_search(s, "uv_map", ob.data, "uv_layers", text="UV Map")
        else:
            sub.prop(s, "uv_map")
        sub.prop(s, "output_dir")
        col.prop(s, "irradiance")
        col.prop(s, "instance_lightmaps")
        col.separator()
        col.row().prop(s, "quality", expand=True)


class _Advanced:
    bl_label = "Advanced"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        s = context.scene.penumbra
        # One column per settings_table.PANEL_GROUPS entry, its settings in the table's order.
        for group, heading, switch in settings_table.PANEL_GROUPS:
            col = layout.column(heading=heading)
            if switch is not None:
                col.prop(s, switch, text="")
                col = col.column()
                col.active = getattr(s, switch)
            for setting in settings_table.PANEL:
                if setting.group == group and setting.name != switch:
                    col.prop(s, setting.name)


def _estimate(report):
    """The solver's own estimate of the bake's relative RMS error, and the object where it is largest."""
    est = report.get("error_estimate")
    if not isinstance(est, dict) or not isinstance(est.get("overall"), (int, float)):
        return "?"
    text = f"{100 * est['overall']:.1f} %"
    objects = est.get("objects") or {}
    if objects:
        worst = max(objects, key=objects.get)
        text += f" (worst {worst}: {100 * objects[worst]:.1f} %)"
    return text


def _textures(report):
    """Convolution links made, and how many candidate pairs were left to ordinary refinement."""
    made = report.get("convolution_links")
    if not isinstance(made, int):
        return "?"
    tried = report.get("convolution_tried", 0) or 0
    return f"{made} of {tried} tried" if tried else f"{made}"


class _Report:
    bl_label = "Last Bake"

    def draw(self, context):
        layout = self.layout
        width = _chars(context)
        outcome, message, report = _last(context)
        if not outcome:
            layout.label(text="No bake yet")
            return
        if outcome == "CANCELLED":
            layout.label(text="Cancelled; the scene is unchanged", icon="CANCEL")
            return
        if outcome == "ERROR":
            _wrap(layout, "Failed: " + message, icon="ERROR", width=width)
            layout.label(text="Nothing in the scene was changed")
            return
        t = report.get("times", {})
        grid = layout.grid_flow(row_major=True, columns=2, even_columns=True, align=True)
        rows = [("Objects baked", f"{len(report.get('objects_baked', []))}"),
                ("Time", f"{t.get('total', 0):.2f} s"),
                ("Export / solve / write", f"{t.get('export', 0):.2f} / {t.get('solve', 0):.2f} / "
                                           f"{t.get('write_back', 0):.2f} s"),
                ("Elements", f"{report.get('elements', '?'):,}" if isinstance(report.get('elements'), int)
                 else "?"),
                ("Links", f"{report.get('links', '?'):,}" if isinstance(report.get('links'), int) else "?"),
                ("Shadow textures", _textures(report)),
                ("Estimated error", _estimate(report)),
                ("Iterations", f"{report.get('iterations', '?')}"),
                ("Residual", f"{report['residual']:.2e}" if isinstance(report.get("residual"), (int, float))
                 else "?")]
        for k, v in rows:
            grid.label(text=k)
            grid.label(text=v)
        skipped = report.get("skipped", [])
        warnings = report.get("warnings", [])
        if skipped:
            box = layout.box()
            box.label(text=f"Skipped ({len(skipped)})", icon="INFO")
            for x in skipped[:MAX_LINES]:
                _wrap(box, f"{x['name']}: {x['reason']}", width=width - 4)
            if len(skipped) > MAX_LINES:
                box.label(text=f"... and {len(skipped) - MAX_LINES} more in the report")
        if warnings:
            box = layout.box()
            box.label(text=f"Warnings ({len(warnings)})", icon="ERROR")
            for w in warnings[:MAX_LINES]:
                _wrap(box, w, width=width - 4)
            if len(warnings) > MAX_LINES:
                box.label(text=f"... and {len(warnings) - MAX_LINES} more in the report")


class PENUMBRA_PT_render(_Main, _Render, bpy.types.Panel):
    pass


class PENUMBRA_PT_render_advanced(_Advanced, _Render, bpy.types.Panel):
    bl_parent_id = "PENUMBRA_PT_render"
    bl_options = {"DEFAULT_CLOSED"}


class PENUMBRA_PT_render_report(_Report, _Render, bpy.types.Panel):
    bl_parent_id = "PENUMBRA_PT_render"


class PENUMBRA_PT_sidebar(_Main, _Sidebar, bpy.types.Panel):
    pass


class PENUMBRA_PT_sidebar_advanced(_Advanced, _Sidebar, bpy.types.Panel):
    bl_parent_id = "PENUMBRA_PT_sidebar"
    bl_options = {"DEFAULT_CLOSED"}


class PENUMBRA_PT_sidebar_report(_Report, _Sidebar, bpy.types.Panel):
    bl_parent_id = "PENUMBRA_PT_sidebar"


class PENUMBRA_PT_object(bpy.types.Panel):
    bl_label = "Penumbra"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "MESH"

    def draw(self, context):
        layout = self.layout
        ob = context.object
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(ob.penumbra_settings, "bake")
        layout.prop(ob.penumbra_settings, "two_sided")
        state = baked_state(ob)
        if not state:
            layout.label(text="Not baked")
            return
        img = bpy.data.images.get(state.get("image", "")) if state.get("image") else None
        if img is not None:
            layout.label(text=f"Lightmap: {img.name} ({img.size[0]} x {img.size[1]}), UV map "
                              f"{state.get('uv_map', '?')}", icon="IMAGE_DATA")
        if state.get("attribute"):
            layout.label(text=f"Color attribute: {state['attribute']}", icon="GROUP_VCOL")


CLASSES = (PENUMBRA_PT_render, PENUMBRA_PT_render_advanced, PENUMBRA_PT_render_report,
           PENUMBRA_PT_sidebar, PENUMBRA_PT_sidebar_advanced, PENUMBRA_PT_sidebar_report, PENUMBRA_PT_object)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
